"""Benchmark: plans for scans past one machine, from measured throughput. Prints
numbers; asserts nothing.

Two scans too large to run here are sampled: random actuators of each, solved on one
core exactly as a scan's chunk solves them (``solve_actuator``), give the core time and
the transitions per actuator; the whole scan's core time, its wall time on this
machine's cores and on a 64-core cluster (both at the parallel efficiency measured for
the n = 5 scan on this machine, given as an argument), and its file size (the bytes of
one transition row, 52 + 2n, measured against a real scan file when one is given).

- n = 6 of the 36-segment library: 1,947,792 actuators of 6 different segments (the
  combinations labrig scans), or 4,496,388 if a segment may be used more than once;
- n = 4 of a 100-segment library: 3,921,225 actuators. No 100 measured segments exist
  here, so it is the braided model at every L_braid 40-49 mm and L_tube 20-29 mm (1 mm
  steps), curves of the same kind as measured ones after their fit.

Run: python tests/benchmarks/bench_scan_plan.py [--sample 300] [--efficiency 0.9]
     [--scan-file scan5.h5] [--write-docs]
"""

import argparse
import math
import os
import random
import time
from pathlib import Path

from labrig.cli.performance_doc import add_write_docs_argument, markdown_table, script_doc

CLUSTER_CORES = 64


def _sample(library, n: int, count: int, *, repeat: bool) -> tuple[float, float, int]:
    """(core seconds per actuator, transitions per actuator, failed actuators) on random
    combinations (with ``repeat``, a segment may be drawn more than once); a failure is
    counted as a scan records it."""
    from labrig.model.scan.scan import solve_actuator

    rng = random.Random(2016)
    items = range(len(library.curves))
    draw = (lambda: rng.choices(items, k=n)) if repeat else (lambda: rng.sample(items, n))
    combos = [tuple(sorted(draw())) for _ in range(count)]
    solve_actuator(library, combos[0])  # compiled code loaded before timing
    found = failed = 0
    started = time.process_time()
    for combo in combos:
        try:
            found += len(solve_actuator(library, combo)[0])
        except Exception:
            failed += 1
    return (time.process_time() - started) / count, found / (count - failed), failed


def _hours(seconds: float) -> str:
    return f"{seconds / 3600:,.1f} h" if seconds >= 3600 else f"{seconds / 60:,.1f} min"


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--sample", type=int, default=300)
    parser.add_argument("--efficiency", type=float, default=0.9, help="of the n = 5 scan")
    parser.add_argument("--scan-file", type=Path, help="a finished scan, to check row bytes")
    add_write_docs_argument(parser)
    args = parser.parse_args()
    doc = script_doc(["scan-plan"], args.write_docs)

    from labrig.model.scan.scan import ScanLibrary, load_library
    from labrig.model.segments.braided import BraidedSegment

    if args.scan_file is not None:
        from labrig.model.scan.scan_file import read_scan

        data = read_scan(args.scan_file)
        measured = args.scan_file.stat().st_size / data.row_stop
        print(
            f"{args.scan_file}: {args.scan_file.stat().st_size / 2**20:,.0f} MiB for "
            f"{data.row_stop:,} rows: {measured:.1f} bytes per row (52 + 2n = {52 + 2 * data.n})"
        )
    analytical = load_library(None)
    hundred = ScanLibrary(
        "braided 1 mm",
        tuple(
            BraidedSegment(b, t).curve(f"B{b}-T{t}") for b in range(40, 50) for t in range(20, 30)
        ),
    )
    plans = [
        ("n = 6 of 36", analytical, 6, math.comb(36, 6), False),
        ("n = 6 of 36, segments may repeat", analytical, 6, math.comb(41, 6), True),
        ("n = 4 of 100", hundred, 4, math.comb(100, 4), False),
    ]
    cores = len(os.sched_getaffinity(0))
    print(f"{args.sample} random actuators per scan, one core; efficiency {args.efficiency}")
    header = (
        "scan",
        "actuators",
        "ms per actuator (one core)",
        "transitions per actuator",
        f"failed of {args.sample}",
        "core time",
        f"this machine ({cores} cores)",
        f"{CLUSTER_CORES}-core cluster",
        "file",
    )
    rows = []
    for label, library, n, total, repeat in plans:
        seconds, per_actuator, failed = _sample(library, n, args.sample, repeat=repeat)
        core_s = seconds * total
        size = total * per_actuator * (52 + 2 * n)
        rows.append(
            (
                label,
                f"{total:,}",
                f"{seconds * 1e3:.2f}",
                f"{per_actuator:.1f}",
                failed,
                _hours(core_s),
                _hours(core_s / (cores * args.efficiency)),
                _hours(core_s / (CLUSTER_CORES * args.efficiency)),
                f"{size / 2**30:.2f} GiB",
            )
        )
    doc.publish("scan-plan", markdown_table(header, rows, right=set(range(1, 9))))


if __name__ == "__main__":
    main()
