"""The library layers stand below the command line: the Python API, the analysis and
the model never import ``labrig.cli`` (a command is one caller of what they build, the
API another), so a notebook does not load click and a command can change its printing
without changing the library."""

import ast
from pathlib import Path

import pytest

import labrig

PACKAGE = Path(labrig.__file__).parent
LIBRARY_LAYERS = ("api", "analysis", "model")


def _imported_modules(source: str, package: str) -> set[str]:
    """Every module ``source`` (a module of ``package``) imports, relative imports
    resolved against ``package``."""
    found: set[str] = set()
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.Import):
            found |= {alias.name for alias in node.names}
        elif isinstance(node, ast.ImportFrom):
            parts = package.split(".")
            base = parts[: len(parts) - node.level + 1] if node.level else []
            target = ".".join([*base, node.module] if node.module else base)
            found |= {target} | {f"{target}.{alias.name}" for alias in node.names}
    return found


def _package_of(path: Path) -> str:
    parts = path.relative_to(PACKAGE.parent).with_suffix("").parts
    return ".".join(parts if path.name == "__init__.py" else parts[:-1])


@pytest.mark.parametrize("layer", LIBRARY_LAYERS)
def test_a_library_layer_never_imports_the_command_line(layer):
    offenders = {
        f"{path.relative_to(PACKAGE.parent)}: {name}"
        for path in sorted((PACKAGE / layer).rglob("*.py"))
        for name in _imported_modules(path.read_text(encoding="utf-8"), _package_of(path))
        if name == "labrig.cli" or name.startswith("labrig.cli.")
    }
    assert not offenders, sorted(offenders)


def test_the_scan_resolves_relative_and_lazy_imports():
    """An import inside a function, or ``from ..cli import x``, is seen as labrig.cli
    (else the check above could pass blind)."""
    source = "def f():\n    from ..cli.model_path import path\n    import labrig.cli\n"
    found = _imported_modules(source, "labrig.api")
    assert {"labrig.cli.model_path", "labrig.cli.model_path.path", "labrig.cli"} <= found
    assert "labrig.cli.x" in _imported_modules("from . import x", "labrig.cli")


# the model is the bottom of the physics: the simulator, the analysis, the runs, the rig
# and the paper's checker stand on it, never the other way round
ABOVE_THE_MODEL = ("analysis", "sim", "run", "rig", "cli", "paper")


def test_the_model_imports_nothing_that_stands_on_it():
    above = tuple(f"labrig.{layer}" for layer in ABOVE_THE_MODEL)
    offenders = {
        f"{path.relative_to(PACKAGE.parent)}: {name}"
        for path in sorted((PACKAGE / "model").rglob("*.py"))
        for name in _imported_modules(path.read_text(encoding="utf-8"), _package_of(path))
        if any(name == a or name.startswith(a + ".") for a in above)
    }
    assert not offenders, sorted(offenders)


def _paper_imports() -> dict[str, set[str]]:
    """Each module of labrig.paper and the modules of labrig.paper it imports."""
    modules = {f"labrig.paper.{p.stem}": p for p in (PACKAGE / "paper").glob("*.py")}
    graph = {}
    for name, path in modules.items():
        found = _imported_modules(path.read_text(encoding="utf-8"), "labrig.paper")
        graph[name] = {m for m in modules if m != name and m in found}
    return graph


def _circles(graph: dict[str, set[str]]) -> list[str]:
    """The modules of ``graph`` that reach themselves through their imports."""
    found = []
    for start in graph:
        seen, todo = set(), list(graph[start])
        while todo:
            module = todo.pop()
            if module == start:
                found.append(start)
                break
            if module not in seen:
                seen.add(module)
                todo.extend(graph.get(module, ()))
    return found


def test_the_papers_checker_has_no_import_circle():
    """The statements' shared module imports no statement module, and nothing in the
    checker's package reaches itself through its imports."""
    graph = _paper_imports()
    assert graph["labrig.paper.statements"] == set()
    assert "labrig.paper.segment_statements" in graph["labrig.paper.checker"]
    assert _circles(graph) == []


def test_the_circle_check_sees_a_circle():
    """A circle through three modules is found (else the check above is blind)."""
    graph = {"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}
    assert sorted(_circles(graph)) == ["a", "b", "c"]


@pytest.mark.parametrize("layer", ("recording", "model", "analysis", "api"))
def test_a_library_layer_reads_the_version_from_its_module(layer):
    """The layers below the package's face take ``__version__`` from ``labrig._version``,
    never from ``labrig`` itself (whose ``__init__`` is the notebook's namespace)."""
    offenders = {
        f"{path.relative_to(PACKAGE.parent)}: {name}"
        for path in sorted((PACKAGE / layer).rglob("*.py"))
        for name in _imported_modules(path.read_text(encoding="utf-8"), _package_of(path))
        if name in ("labrig", "labrig.__version__")
    }
    assert not offenders, sorted(offenders)


def test_the_version_is_one_figure():
    from importlib.metadata import version

    from labrig import _version

    assert labrig.__version__ == _version.__version__ == version("labrig")
