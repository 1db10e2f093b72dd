"""Validated YAML files: safe loading, strict schemas, and errors a person can act on.

Protocols and rig configurations are data, never code: they are read as
``yaml.safe_load`` reads them, with bounds, no duplicate keys and YAML 1.2's numbers
(``labrig.config.bounded_yaml``), and validated by a strict pydantic model (unknown keys,
strings where numbers belong, and infinite or NaN numbers are errors). A validation
error names the file, the line (from the YAML node tree) and the key path, and says
what is allowed.
"""

from __future__ import annotations

import re
from collections.abc import Iterable
from typing import Annotated, TypeVar

import yaml
from pydantic import AfterValidator, BaseModel, ConfigDict, ValidationError

from labrig.config.bounded_yaml import NumberError, load_with_nodes
from labrig.errors import InputError

Model = TypeVar("Model", bound=BaseModel)


class Strict(BaseModel):
    """Forbid unknown keys, silent type coercion from strings, and infinite or NaN
    numbers (``.inf`` as a hold or a limit would make a run endless or an interlock
    blind)."""

    model_config = ConfigDict(extra="forbid", frozen=True, strict=True, allow_inf_nan=False)


def _printable(line_breaks: bool):
    """A validator refusing control characters (NUL and the like; tabs and line breaks
    too unless ``line_breaks``): they end strings early in HDF5 and C libraries, and
    make names that cannot be file names."""
    allowed = "\n\t" if line_breaks else ""

    def check(value):
        if not isinstance(value, str):  # the other member of a union (a camera index)
            return value
        for position, char in enumerate(value, start=1):
            if not char.isprintable() and char not in allowed:
                raise ValueError(
                    f"character {position} is a control character (code {ord(char)}); "
                    + ("only text and line breaks" if line_breaks else "only printable text")
                )
        return value

    return AfterValidator(check)


_KEY = re.compile(r"[A-Za-z_][A-Za-z0-9_-]{0,63}")

# a name or a path on one line, free text, and a device's index or path
Line = Annotated[str, _printable(line_breaks=False)]
Text = Annotated[str, _printable(line_breaks=True)]
IndexOrLine = Annotated[int | str, _printable(line_breaks=False)]


def parse_yaml_model(
    text: str,
    filename: str,
    model: type[Model],
    *,
    what: str,
    hide: Iterable[str] = (),
) -> Model:
    """Parse ``text`` and validate it as ``model``; InputError with file, line and key.

    ``hide`` lists tagged-union tags that pydantic repeats in error locations.
    """
    try:
        data, root = load_with_nodes(text)
    except NumberError as exc:
        line = exc.problem_mark.line + 1
        where = exc.path or "(top level)"
        raise InputError(f"{filename}: line {line}: {where}: {exc.problem}") from None
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        line = f" line {mark.line + 1}:" if mark is not None else ""
        problem = getattr(exc, "problem", None) or str(exc)
        context, context_mark = getattr(exc, "context", None), getattr(exc, "context_mark", None)
        if context and context_mark is not None:
            problem += f" ({context} that starts on line {context_mark.line + 1})"
        raise InputError(f"{filename}:{line} not valid YAML: {problem}") from None
    if not isinstance(data, dict):
        keys = ", ".join(model.model_fields)
        raise InputError(f"{filename}: {what} is a YAML mapping with keys {keys}")
    try:
        return model.model_validate(data)
    except ValidationError as exc:
        raise InputError(_describe(exc, root, filename, set(hide))) from None


def _describe(exc: ValidationError, root: yaml.Node | None, filename: str, hide: set) -> str:
    """One line per problem: file:line: key.path: what is wrong and what is allowed."""
    lines = []
    for error in exc.errors():
        loc = _without_tags(error["loc"], hide)
        node = _node_at(root, loc)
        line = f"line {node.start_mark.line + 1}" if node is not None else "line ?"
        key_path = _format_loc(loc) or "(top level)"
        lines.append(f"{filename}: {line}: {key_path}: {_message(error)}")
    first, *rest = lines
    if rest:
        return first + "\n" + "\n".join(rest)
    return first


def _without_tags(loc: tuple, hide: set) -> list:
    """Drop the union tag pydantic inserts before a step's own key (steps[1].repeat.repeat)."""
    cleaned: list = []
    for part in loc:
        if cleaned and part == cleaned[-1] and part in hide:
            continue
        cleaned.append(part)
    return cleaned


def _message(error: dict) -> str:
    kind = error["type"]
    if kind == "extra_forbidden":
        return "unknown key (check the spelling; the schema lists the allowed keys)"
    if kind == "missing":
        return "required key is missing"
    message = error["msg"]
    return message.removeprefix("Value error, ")


def _format_loc(loc: list) -> str:
    text = ""
    for part in loc:
        if isinstance(part, int):
            text += f"[{part}]"
            continue
        # an unknown key is shown only if it looks like one: a file that is no YAML
        # config (a mistyped path) would otherwise show its lines as keys
        name = part if _KEY.fullmatch(str(part)) else "(a key that is no name)"
        text += f".{name}" if text else name
    return text


def _node_at(root: yaml.Node | None, loc: list) -> yaml.Node | None:
    """The YAML node at a pydantic error location (or its nearest existing parent)."""
    node = root
    for part in loc:
        child = None
        if isinstance(node, yaml.MappingNode):
            for key, value in node.value:
                if key.value == part:
                    child = value
                    break
        elif (
            isinstance(node, yaml.SequenceNode)
            and isinstance(part, int)
            and 0 <= part < len(node.value)
        ):
            child = node.value[part]
        if child is None:
            return node
        node = child
    return node
