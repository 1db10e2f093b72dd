"""The benchmarks' tables in ``docs/performance.md``, each rewritten by its own benchmark.

Every benchmark owns one or more sections of that file, each between the lines
``<!-- bench:NAME -->`` and ``<!-- /bench:NAME -->``. Run with ``--write-docs`` it
replaces what lies between its own markers (a table and one line saying when, where and
under what load it was measured) and touches nothing else, so each figure in the file
comes with its date and a command that measures it again. The prose around the sections
is written by people and never regenerated.

Benchmark scripts (``tests/benchmarks``) and ``labrig bench`` share this module, which
is why it lives in the package rather than beside the scripts.
"""

from __future__ import annotations

import os
import platform
import re
import shlex
import sys
import time
from collections.abc import Iterable, Sequence
from pathlib import Path

from labrig.errors import InputError

# A clone's docs folder beside the package's source; an installed copy has none, and
# --write-docs says so instead of writing somewhere unexpected.
PERFORMANCE_DOC = Path(__file__).resolve().parents[2] / "docs" / "performance.md"

_NAME = re.compile(r"[a-z0-9][a-z0-9-]*")


def start_marker(name: str) -> str:
    return f"<!-- bench:{name} -->"


def end_marker(name: str) -> str:
    return f"<!-- /bench:{name} -->"


def markdown_table(header: Sequence[str], rows: Iterable[Sequence[object]], right=()) -> str:
    """A Markdown table; the columns whose index is in ``right`` are right-aligned
    (numbers), the others left."""
    rule = "|" + "|".join("---:" if i in right else "---" for i in range(len(header))) + "|"
    lines = ["| " + " | ".join(str(cell) for cell in row) + " |" for row in rows]
    return "\n".join(["| " + " | ".join(header) + " |", rule, *lines])


def replace_section(text: str, name: str, body: str, where: str = "the document") -> str:
    """``text`` with the lines between the markers of section ``name`` replaced by
    ``body``; every other character of ``text`` is kept as it was."""
    lines = text.splitlines(keepends=True)
    first, last = section_lines(lines, name, where)
    inner = [line + "\n" for line in body.strip("\n").split("\n")] if body.strip() else []
    return "".join([*lines[: first + 1], *inner, *lines[last:]])


def section_lines(lines: Sequence[str], name: str, where: str) -> tuple[int, int]:
    """The indices of section ``name``'s start and end marker lines. Each marker must
    stand alone on its line, once, the start before the end: anything else is an error
    naming ``where`` and the section."""
    if not _NAME.fullmatch(name):
        raise InputError(f"section name {name!r}: lower-case letters, digits and '-' only")
    stripped = [line.strip() for line in lines]
    found = []
    for marker in (start_marker(name), end_marker(name)):
        at = [i + 1 for i, line in enumerate(stripped) if line == marker]
        if not at:
            raise InputError(
                f"{where}: no line {marker!r}; section {name!r} needs the two lines "
                f"{start_marker(name)} and {end_marker(name)} where its table belongs"
            )
        if len(at) > 1:
            raise InputError(f"{where}: {marker!r} is on lines {at}; it must appear once")
        found.append(at[0] - 1)
    first, last = found
    if last < first:
        raise InputError(f"{where}: {end_marker(name)!r} comes before {start_marker(name)!r}")
    return first, last


def machine() -> str:
    """'2-core Intel(R) Xeon(R) Processor VM': cores, processor model, and whether a
    hypervisor runs it (whose other tenants make its speed drift)."""
    model = platform.processor() or platform.machine()
    try:
        cpuinfo = Path("/proc/cpuinfo").read_text()
    except OSError:
        cpuinfo = ""
    names = re.findall(r"^model name\s*:\s*(.+)$", cpuinfo, flags=re.MULTILINE)
    if names:
        model = names[0].strip()
    virtual = bool(re.search(r"^flags\s*:.*\bhypervisor\b", cpuinfo, flags=re.MULTILINE))
    return f"{os.cpu_count()}-core {model}{' VM' if virtual else ''}"


def command_line(argv: Sequence[str] | None = None) -> str:
    """The command that measures again, as a person types it from the repository's root
    (``--write-docs`` left out)."""
    argv = list(sys.argv if argv is None else argv)
    args = [a for a in argv[1:] if a != "--write-docs"]
    program = Path(argv[0])
    if program.suffix == ".py":
        root = PERFORMANCE_DOC.parents[1]
        if program.resolve().is_relative_to(root):
            program = program.resolve().relative_to(root)
        return shlex.join(["python", program.as_posix(), *args])
    return shlex.join(["labrig", *args])


class PerformanceDoc:
    """What one benchmark run reports: each table printed, and with ``write`` also put
    into its section of ``path`` with the dated line.

    Made when the benchmark starts: it checks at once that every section it will write
    exists (a long benchmark must not fail at its end) and notes the load average then,
    since on a shared machine the load is part of the figure.
    """

    def __init__(self, sections: Iterable[str], write: bool, path: Path | None = None):
        self.write, self.path = write, PERFORMANCE_DOC if path is None else path
        self.load_at_start = os.getloadavg()[0]
        self.command = command_line()
        if write:
            lines = self._read().splitlines()
            for name in sections:
                section_lines(lines, name, str(self.path))

    def _read(self) -> str:
        try:
            return self.path.read_text(encoding="utf-8")
        except FileNotFoundError:
            raise InputError(
                f"--write-docs: {self.path} not found; run the benchmark from a clone of the "
                "repository, whose docs/performance.md holds the tables"
            ) from None

    def dated_line(self) -> str:
        now = time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime())
        return (
            f"Measured {now} on a {machine()}, Python {platform.python_version()}; "
            f"load average {self.load_at_start:.1f} at the start, "
            f"{os.getloadavg()[0]:.1f} at the end. `{self.command}`"
        )

    def publish(self, name: str, table: str) -> None:
        """Print ``table``, and write it (``write_section``)."""
        print(table, flush=True)
        self.write_section(name, table)

    def write_section(self, name: str, table: str) -> None:
        """With ``write``, replace section ``name`` by ``table`` and the dated line."""
        if not self.write:
            return
        body = f"{table.strip()}\n\n{self.dated_line()}"
        self.path.write_text(
            replace_section(self._read(), name, body, where=str(self.path)), encoding="utf-8"
        )
        print(f"written: section {name!r} of {self.path}", file=sys.stderr)


def add_write_docs_argument(parser) -> None:
    """The scripts' ``--write-docs`` flag (argparse)."""
    parser.add_argument(
        "--write-docs",
        action="store_true",
        help="also replace this benchmark's tables in docs/performance.md",
    )


def script_doc(sections: Iterable[str], write: bool) -> PerformanceDoc:
    """A benchmark script's ``PerformanceDoc``: a missing file or section ends the script
    with one line, before it measures anything."""
    try:
        return PerformanceDoc(sections, write)
    except InputError as exc:
        raise SystemExit(f"error: {exc}") from None
