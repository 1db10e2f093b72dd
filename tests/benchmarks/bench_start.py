"""Benchmark: how long a command takes from the shell, cold (numba's compile cache and
labrig's tabulated segments empty, as on a fresh install) and warm (the same command
again). Prints numbers; asserts nothing.

Each command runs in a fresh process, as a user runs it, with ``NUMBA_CACHE_DIR`` and
``LABRIG_CACHE_DIR`` pointed at a new temporary folder, so nothing compiled or
tabulated before is found: the first run
is a fresh install's first command (Python's own byte-code caches are kept, as pip
writes them at install time). Rows:

- ``labrig model path B48-T30 B50-T20`` as the console script runs it (one actuator:
  the inner loops as plain Python, nothing compiled; ``labrig.model.actuator.jit``);
- the same with ``LABRIG_JIT=numba`` (compiled), what it would cost compiled;
- ``labrig model scan --n 2`` (630 pairs): on an empty cache as plain Python, where
  compiling would not pay (``labrig.model.scan.plan``); the larger scans compile;
- ``labrig --help`` and ``labrig run protocols/demo.yaml --dry-run``.

Run: python tests/benchmarks/bench_start.py [--repeat 5] [--write-docs]
"""

import argparse
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from labrig.cli.performance_doc import add_write_docs_argument, markdown_table, script_doc

REPO = Path(__file__).resolve().parents[2]


def _seconds(args: list[str], env: dict[str, str]) -> float:
    started = time.perf_counter()
    subprocess.run(
        [sys.executable, "-m", "labrig", *args],
        env=env,
        cwd=REPO,
        check=True,
        stdout=subprocess.DEVNULL,
    )
    return time.perf_counter() - started


def _cold_and_warm(args, repeat: int, *, jit: str | None = None, out: Path | None = None):
    """(cold, median warm) seconds of ``labrig ARGS`` with empty caches."""
    with tempfile.TemporaryDirectory() as cache:
        env = {k: v for k, v in os.environ.items() if k != "LABRIG_JIT"}
        env["NUMBA_CACHE_DIR"] = cache
        env["LABRIG_CACHE_DIR"] = str(Path(cache) / "segments")
        # each command alone: no compile left running in the background by a scan
        env["LABRIG_BACKGROUND_COMPILE"] = "0"
        if jit is not None:
            env["LABRIG_JIT"] = jit
        times = []
        for _ in range(repeat + 1):
            if out is not None:
                out.unlink(missing_ok=True)
            times.append(_seconds(args, env))
    return times[0], statistics.median(times[1:])


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--repeat", type=int, default=5, help="warm runs per command")
    add_write_docs_argument(parser)
    args = parser.parse_args()
    doc = script_doc(["start"], args.write_docs)

    path = ["model", "path", "B48-T30", "B50-T20"]
    rows = []
    with tempfile.TemporaryDirectory() as folder:
        scan_out = Path(folder) / "pairs.h5"
        scan = ["model", "scan", "--n", "2", "--out", str(scan_out)]
        commands = [
            ("labrig model path B48-T30 B50-T20", path, None, None),
            ("the same, LABRIG_JIT=numba (compiled)", path, "numba", None),
            ("labrig model scan --n 2 (plain Python on an empty cache)", scan, None, scan_out),
            ("labrig --help", ["--help"], None, None),
            (
                "labrig run protocols/demo.yaml --dry-run",
                ["run", "protocols/demo.yaml", "--dry-run"],
                None,
                None,
            ),
        ]
        for label, command, jit, out in commands:
            cold, warm = _cold_and_warm(command, args.repeat, jit=jit, out=out)
            rows.append((label, cold, warm))
            print(f"  {label}: cold {cold:.2f} s, warm {warm:.2f} s", file=sys.stderr)
    header = ("command", "cold: empty caches (s)", "warm: median of later runs (s)")
    table = [(label, f"{cold:.2f}", f"{warm:.2f}") for label, cold, warm in rows]
    doc.publish("start", markdown_table(header, table, right={1, 2}))


if __name__ == "__main__":
    main()
