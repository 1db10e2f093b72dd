"""docs/performance.md's sections: a benchmark replaces exactly its own, every other
character of the file stays as it was, and a missing or malformed marker is an error
that names the file and the section before anything is measured or written."""

import re
from pathlib import Path

import pytest

from labrig.cli import main
from labrig.cli.performance_doc import (
    PERFORMANCE_DOC,
    PerformanceDoc,
    command_line,
    markdown_table,
    replace_section,
    script_doc,
    section_lines,
)
from labrig.errors import InputError

REPO = Path(__file__).resolve().parents[2]

DOC = """# Performance

Prose a person wrote, kept as it is.

<!-- bench:alpha -->
| old | table |
|---|---|
| 1 | 2 |

Measured long ago.
<!-- /bench:alpha -->

More prose between the sections.

<!-- bench:beta -->
| beta | stays |
<!-- /bench:beta -->

<!-- bench:empty -->
<!-- /bench:empty -->
Closing words.
"""


def test_only_the_named_section_changes():
    new = replace_section(DOC, "alpha", "| new |\n|---|\n| 3 |")
    before, _, after = DOC.partition("<!-- bench:alpha -->\n")
    _, _, rest = after.partition("<!-- /bench:alpha -->")
    assert (
        new == before + "<!-- bench:alpha -->\n| new |\n|---|\n| 3 |\n<!-- /bench:alpha -->" + rest
    )
    assert "| beta | stays |" in new and new.endswith("Closing words.\n")


def test_an_empty_section_is_filled_and_a_filled_one_emptied():
    filled = replace_section(DOC, "empty", "\n\n| x |\n\n")
    assert "<!-- bench:empty -->\n| x |\n<!-- /bench:empty -->\n" in filled
    emptied = replace_section(filled, "empty", "")
    assert emptied == DOC


def test_replacing_twice_gives_the_same_file():
    once = replace_section(DOC, "beta", "| b |")
    assert replace_section(once, "beta", "| b |") == once
    assert once.replace("| b |", "| beta | stays |") == DOC


@pytest.mark.parametrize(
    ("text", "message"),
    [
        (DOC.replace("<!-- bench:beta -->\n", ""), "no line '<!-- bench:beta -->'"),
        (DOC.replace("<!-- /bench:beta -->\n", ""), "no line '<!-- /bench:beta -->'"),
        (DOC + "<!-- bench:beta -->\n", "'<!-- bench:beta -->' is on lines [15, 22]"),
        (
            DOC.replace("<!-- bench:beta -->", "@")
            .replace("<!-- /bench:beta -->", "<!-- bench:beta -->")
            .replace("@", "<!-- /bench:beta -->"),
            "'<!-- /bench:beta -->' comes before '<!-- bench:beta -->'",
        ),
        # a marker inside a line of prose is not a marker
        (DOC.replace("<!-- bench:beta -->", "see <!-- bench:beta -->"), "no line"),
    ],
)
def test_a_missing_or_misplaced_marker_is_an_error(text, message):
    with pytest.raises(InputError) as error:
        replace_section(text, "beta", "| x |", where="docs/performance.md")
    assert str(error.value).startswith("docs/performance.md: ")
    assert message in str(error.value)


def test_a_section_name_is_checked():
    with pytest.raises(InputError, match="lower-case letters"):
        replace_section(DOC, "Alpha -->", "x")


def test_publish_writes_the_table_and_one_dated_line(tmp_path, capsys):
    path = tmp_path / "performance.md"
    path.write_text(DOC)
    doc = PerformanceDoc(["alpha", "empty"], write=True, path=path)
    table = markdown_table(("case", "ms"), [("a", "1.5"), ("b", "20.0")], right={1})
    doc.publish("empty", table)
    assert capsys.readouterr().out == table + "\n"
    text = path.read_text()
    body = text.split("<!-- bench:empty -->\n")[1].split("<!-- /bench:empty -->")[0]
    lines = body.splitlines()
    assert lines[:4] == ["| case | ms |", "|---|---:|", "| a | 1.5 |", "| b | 20.0 |"]
    assert lines[4] == ""
    assert len(lines) == 6
    assert re.fullmatch(
        r"Measured \d{4}-\d\d-\d\d \d\d:\d\d UTC on a \d+-core .+, Python [\d.]+; "
        r"load average [\d.]+ at the start, [\d.]+ at the end\. `.+`",
        lines[5],
    ), lines[5]
    assert text.replace(body, "") == DOC


def test_without_write_it_only_prints(tmp_path, capsys):
    path = tmp_path / "performance.md"
    path.write_text(DOC)
    PerformanceDoc(["nowhere"], write=False, path=path).publish("nowhere", "| t |")
    assert capsys.readouterr().out == "| t |\n"
    assert path.read_text() == DOC


def test_a_missing_section_stops_the_benchmark_before_it_measures(tmp_path):
    path = tmp_path / "performance.md"
    path.write_text(DOC)
    with pytest.raises(InputError, match=f"{re.escape(str(path))}: no line '<!-- bench:gamma"):
        PerformanceDoc(["alpha", "gamma"], write=True, path=path)
    with pytest.raises(InputError, match="not found; run the benchmark from a clone"):
        PerformanceDoc(["alpha"], write=True, path=tmp_path / "missing.md")
    assert path.read_text() == DOC


def test_a_script_ends_with_one_line(tmp_path, monkeypatch):
    monkeypatch.setattr("labrig.cli.performance_doc.PERFORMANCE_DOC", tmp_path / "none.md")
    with pytest.raises(SystemExit) as exited:
        script_doc(["alpha"], write=True)
    assert str(exited.value).startswith("error: --write-docs: ")
    assert script_doc(["alpha"], write=False).write is False


def test_bench_model_checks_its_sections_before_solving(tmp_path, monkeypatch, capsys):
    path = tmp_path / "performance.md"
    path.write_text(DOC)
    monkeypatch.setattr("labrig.cli.performance_doc.PERFORMANCE_DOC", path)
    with pytest.raises(SystemExit) as exited:
        main(["bench", "model", "--quick", "--write-docs"])
    assert exited.value.code == 2
    assert "no line '<!-- bench:model-solvers -->'" in capsys.readouterr().err
    assert path.read_text() == DOC


def test_the_command_to_measure_again():
    script = str(REPO / "tests" / "benchmarks" / "bench_path.py")
    assert command_line([script, "--triples", "5", "--write-docs"]) == (
        "python tests/benchmarks/bench_path.py --triples 5"
    )
    assert command_line(["/venv/bin/labrig", "bench", "model", "--scans", "", "--write-docs"]) == (
        "labrig bench model --scans ''"
    )


def test_every_section_a_benchmark_writes_is_in_the_repository_doc():
    """The names the benchmarks publish, read from their source, each have their two
    markers in the doc they write (docs/performance.md unless the benchmark names another
    docs page), so --write-docs cannot fail at a benchmark's end."""
    sources = [
        *(REPO / "tests" / "benchmarks").glob("bench_*.py"),
        REPO / "labrig/cli/benchmark.py",
    ]
    published = []
    for source in sources:
        text = source.read_text()
        other = re.search(r'"docs" / "([a-z]+)" / "([a-z0-9-]+\.md)"', text)
        doc = REPO / "docs" / other[1] / other[2] if other else PERFORMANCE_DOC
        pattern = r'(?:publish|write_section)\(\s*"([a-z0-9-]+)"'
        published += [(doc, name) for name in re.findall(pattern, text)]
    assert len(published) >= 15  # the pattern still finds them
    assert any(doc != PERFORMANCE_DOC for doc, _ in published)  # and the other pages
    for doc, name in sorted(set(published)):
        section_lines(doc.read_text().splitlines(), name, str(doc))
    lines = PERFORMANCE_DOC.read_text().splitlines()
    section_lines(lines, "soak", str(PERFORMANCE_DOC))
