"""The paper's statements on every library: the table of docs/explanation/calibration.md.

Run: python tests/benchmarks/bench_paper_statements.py [--libraries paper calibrated]
[--write-docs] [--json-dir DIR] [--reuse-json]

Each library is ``labrig model paper --library NAME --json`` in a process of its own;
the table has one row a statement (its key, what the paper says and the tolerance) and
one column a library: labrig's value, whether it holds and the statement's role there
where it is not a prediction. With ``--write-docs`` it replaces the section between
``<!-- bench:statements -->`` and its end marker in calibration.md, with the date, the
machine and its load (the verdicts are the same on any machine; the seconds are not).
With ``--reuse-json`` a library whose document is already in ``--json-dir`` (written by
``labrig model paper --library NAME --json`` from the same code) is read, not run again.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from labrig.cli.performance_doc import PerformanceDoc, add_write_docs_argument, markdown_table

CALIBRATION_DOC = Path(__file__).resolve().parents[2] / "docs" / "explanation" / "calibration.md"
LIBRARIES = ("paper", "paper-r", "paper-gent", "paper-clamped", "calibrated", "si")


def statements(library: str) -> tuple[dict, float]:
    """The library's JSON document and the seconds it took."""
    start = time.perf_counter()
    out = subprocess.run(
        [sys.executable, "-m", "labrig", "model", "paper", "--library", library, "--json"],
        check=True,
        capture_output=True,
        text=True,
    ).stdout
    return json.loads(out), time.perf_counter() - start


def _escape(text: str) -> str:
    return text.replace("|", "/")


def _cell(statement: dict) -> str:
    verdict = "**yes**" if statement["holds"] else "no"
    role = "" if statement["role"] == "prediction" else f" ({statement['role']})"
    return f"{_escape(statement['labrig'])}: {verdict}{role}"


def table(documents: dict[str, dict]) -> str:
    first = next(iter(documents.values()))
    header = ["statement", "paper", "tolerance"] + [
        f"`{name}:` ({doc['fitted_constants']} fitted)" for name, doc in documents.items()
    ]
    by_library = {name: {s["key"]: s for s in doc["statements"]} for name, doc in documents.items()}
    rows = [
        [
            f"{_escape(s['statement'])} `{s['key']}`",
            _escape(s["paper"]),
            _escape(s["tolerance"]),
            *(_cell(by_library[name][s["key"]]) for name in documents),
        ]
        for s in first["statements"]
    ]
    count = len(first["statements"])
    rows.append(
        ["**holding**", "", ""] + [f"**{doc['holding']} of {count}**" for doc in documents.values()]
    )
    roles = []
    for doc in documents.values():
        kinds = {}
        for s in doc["statements"]:
            kinds.setdefault(s["role"], []).append(s["holds"])
        roles.append(
            "; ".join(f"{role} {sum(held)} of {len(held)}" for role, held in sorted(kinds.items()))
        )
    rows.append(["holding by role", "", "", *roles])
    return markdown_table(header, rows)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--libraries", nargs="+", default=list(LIBRARIES))
    parser.add_argument("--json-dir", type=Path, help="also keep each library's JSON there")
    parser.add_argument(
        "--reuse-json", action="store_true", help="read a library's JSON from --json-dir if there"
    )
    add_write_docs_argument(parser)
    args = parser.parse_args()
    doc = PerformanceDoc(["statements"], args.write_docs, path=CALIBRATION_DOC)
    documents = {}
    if args.reuse_json and args.json_dir is None:
        parser.error("--reuse-json reads from --json-dir: give it")
    for library in args.libraries:
        kept = args.json_dir / f"{library}.json" if args.json_dir is not None else None
        if args.reuse_json and kept.is_file():
            documents[library] = json.loads(kept.read_text())
            print(f"{library}: {documents[library]['holding']} hold, from {kept}", file=sys.stderr)
            continue
        documents[library], seconds = statements(library)
        print(f"{library}: {documents[library]['holding']} hold, {seconds:.0f} s", file=sys.stderr)
        if args.json_dir is not None:
            args.json_dir.mkdir(parents=True, exist_ok=True)
            (args.json_dir / f"{library}.json").write_text(json.dumps(documents[library]))
    doc.publish("statements", table(documents))


if __name__ == "__main__":
    main()
