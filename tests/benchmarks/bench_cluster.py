"""Benchmark: a scan on a 2-worker dask.distributed cluster on this machine against the
local process pool of 2 (``labrig model scan --scheduler`` against ``--workers 2``).
Prints numbers; asserts nothing but that the two files hold the same transitions.

The cluster is a real one over TCP on 127.0.0.1: distributed's LocalCluster with two
worker processes of one thread each. Each command runs in a fresh process, as a user
runs it; the cluster's first scan includes its workers' imports and loading the compiled
model, so the cluster is warmed up by a first scan and the second is timed too.

Run: python tests/benchmarks/bench_cluster.py [--n 3] [--repeat 2] [--write-docs]
"""

import argparse
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from labrig.cli.performance_doc import add_write_docs_argument, markdown_table, script_doc


def _scan(n: int, out: Path, *extra: str) -> tuple[float, float]:
    """(wall time of the command, the scan's own time from the file)."""
    from labrig.model.scan.scan_file import read_scan

    command = [sys.executable, "-m", "labrig", "model", "scan", "--n", str(n), "--out", str(out)]
    started = time.perf_counter()
    subprocess.run([*command, *extra], check=True, stdout=subprocess.DEVNULL)
    return time.perf_counter() - started, read_scan(out).elapsed_s


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--n", type=int, default=3)
    parser.add_argument("--repeat", type=int, default=2)
    add_write_docs_argument(parser)
    args = parser.parse_args()
    doc = script_doc(["cluster"], args.write_docs)

    import numpy as np
    from distributed import LocalCluster

    from labrig.model.scan.scan_file import read_scan

    rows = []
    with (
        tempfile.TemporaryDirectory() as folder,
        LocalCluster(
            n_workers=2,
            threads_per_worker=1,
            processes=True,
            host="127.0.0.1",
            dashboard_address=":0",
        ) as cluster,
    ):
        for i in range(args.repeat):
            local = Path(folder) / f"local{i}.h5"
            rows.append(("local pool, 2 processes", i, *_scan(args.n, local, "--workers", "2")))
            remote = Path(folder) / f"cluster{i}.h5"
            address = cluster.scheduler_address
            rows.append(
                (
                    "dask LocalCluster, 2 workers x 1 thread",
                    i,
                    *_scan(args.n, remote, "--scheduler", address),
                )
            )
            a, b = read_scan(local), read_scan(remote)
            assert np.array_equal(a.actuator, b.actuator)
            for name, column in a.columns.items():
                assert np.array_equal(column, b.columns[name]), name
        total = read_scan(Path(folder) / "local0.h5").n_combinations
    print(f"scan n = {args.n} ({total:,} actuators) of the 36-segment library; same rows: yes")
    header = ("engine", "run", "command (s)", "scan (s)", "actuators/s")
    table = [
        (engine, i + 1, f"{wall:.1f}", f"{scan:.1f}", f"{total / scan:,.0f}")
        for engine, i, wall, scan in rows
    ]
    doc.publish("cluster", markdown_table(header, table, right={1, 2, 3, 4}))


if __name__ == "__main__":
    main()
