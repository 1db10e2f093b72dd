"""Benchmark: the fault soak, seed by seed, and how fast each kind of fault stops the pump.

Run: python tests/benchmarks/bench_soak.py [--runs 300] [--seeds 1 2] [--write-docs]

Each seed is ``labrig rig soak --sim --runs N --seed S`` (labrig/rig/soak.py): one table
row a seed (runs safe, runs of each kind, the worst stop, how many runs told the operator
that the stop was not confirmed, memory, wall time), then one row a fault kind over all
seeds: rig seconds from the fault to the plunger's last movement (median and worst) and
the median wall time of one run. Rig time is virtual, so every figure but the wall times
is the same on any machine under any load.
"""

from __future__ import annotations

import argparse
import statistics
import sys
from collections import defaultdict
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from labrig.cli.performance_doc import add_write_docs_argument, markdown_table, script_doc
from labrig.rig.soak import FAULTS, soak
from labrig.run.pump_stop import PUMP_STOP_NOT_CONFIRMED


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=300)
    parser.add_argument("--seeds", type=int, nargs="+", default=[1, 2])
    add_write_docs_argument(parser)
    args = parser.parse_args()
    doc = script_doc(["soak"], args.write_docs)

    seed_rows, by_kind = [], defaultdict(list)
    for seed in args.seeds:
        summary, verdicts = soak(args.runs, seed)
        per_kind = summary.faults.values()
        told = sum(v.reason.startswith(PUMP_STOP_NOT_CONFIRMED) for v in verdicts)
        kept = sum(v.finalised and v.samples_kept and v.frames_kept for v in verdicts)
        seed_rows.append(
            (
                seed,
                f"{summary.safe} / {summary.runs}",
                f"{min(per_kind)}-{max(per_kind)}",
                f"{summary.max_stop_s:.2f} s",
                told,
                f"{kept} / {summary.runs}",
                f"{summary.rss_start_mb:.0f} -> {summary.rss_end_mb:.0f} MB",
                f"{summary.wall_s / 60:.0f} min {summary.wall_s % 60:.0f} s",
            )
        )
        for verdict in verdicts:
            by_kind[verdict.fault].append(verdict)
        for verdict in verdicts:
            if verdict.problems:
                print(f"seed {seed} run {verdict.run} {verdict.fault}: {verdict.problems}")

    seeds_table = markdown_table(
        (
            "seed",
            "runs safe",
            "runs of each kind",
            "pump stopped after the fault (worst)",
            "told the stop was not confirmed",
            "files finalised, samples and frames kept",
            "memory after warm-up -> end",
            "wall",
        ),
        seed_rows,
    )
    kind_rows = []
    for kind in FAULTS:
        verdicts = by_kind.get(kind, [])
        if not verdicts:
            continue
        stops = [v.stopped_after_s for v in verdicts]
        kind_rows.append(
            (
                kind,
                len(verdicts),
                sum(v.safe for v in verdicts),
                f"{statistics.median(stops):.2f} s",
                f"{max(stops):.2f} s",
                f"{FAULTS[kind].stop_s:g} s",
                f"{statistics.median(v.wall_s for v in verdicts):.2f} s",
            )
        )
    kinds_table = markdown_table(
        ("fault", "runs", "safe", "stop, median", "stop, worst", "allowed", "wall a run"),
        kind_rows,
        right=(1, 2),
    )
    doc.publish("soak", f"{seeds_table}\n\nPer fault kind, over the seeds:\n\n{kinds_table}")


if __name__ == "__main__":
    main()
