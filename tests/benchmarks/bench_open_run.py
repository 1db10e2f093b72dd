"""Benchmark: ``labrig.open_run`` on a 30-minute simulated run. Prints numbers; asserts
nothing.

A 30-minute run is recorded once (``protocols/demo.yaml`` repeated 15 times: 1 kHz
pressure, a 30 fps camera; ``labrig run --sim``), then each way of reading it runs in a
fresh process, which reports its wall time and the memory it added: its peak resident
set (``ru_maxrss``) less its resident set once labrig, pandas and xarray were imported.
Reading a series one repetition at a time should hold about one repetition, however
many the run has; the eager reader the commands use (``load_run``: every series at
once) is measured beside it for scale.

Run: python tests/benchmarks/bench_open_run.py [--run FILE.h5] [--write-docs]
(--run reuses a recorded file instead of recording one.)
"""

import argparse
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from labrig.cli.performance_doc import add_write_docs_argument, markdown_table, script_doc

ROOT = Path(__file__).resolve().parents[2]
REPETITIONS = 15  # of the demo's 124 s: 31 min of rig time

# each case: the code timed, after `run = labrig.open_run(PATH)` where the case says so
CASES = {
    "open_run (metadata, sizes)": "run = labrig.open_run(PATH)",
    "open_run + the repetitions table": "run = labrig.open_run(PATH); run.repetitions",
    "open_run + one repetition's pressure DataFrame (first DataFrame of data)": (
        "run = labrig.open_run(PATH); run.raw_table(8, 'pressure')"
    ),
    "open_run + a 10 s window of pressure (Dataset)": (
        "run = labrig.open_run(PATH); t0 = float(run.repetitions.t_start_s[8]); "
        "run.raw(8, 'pressure', start_s=t0 + 50, stop_s=t0 + 60)"
    ),
    "open_run + every repetition's pressure, one at a time": (
        "run = labrig.open_run(PATH)\n"
        "for i in range(1, run.n_repetitions + 1): run.raw_table(i, 'pressure')"
    ),
    "open_run + the averaged curves (stored analysis)": "run = labrig.open_run(PATH); run.curves",
    "for scale: load_run, every series at once (what the commands read)": (
        "from labrig.analysis.runfile import load_run; load_run(PATH)"
    ),
}

PROBE = """
import json, resource, sys, time
import pandas, xarray
import labrig
labrig.open_run  # the API's modules imported
def rss_kib():
    for line in open("/proc/self/status"):
        if line.startswith("VmRSS:"):
            return int(line.split()[1])
PATH = sys.argv[1]
base = rss_kib()
start = time.perf_counter()
exec(sys.argv[2])
seconds = time.perf_counter() - start
peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
print(json.dumps({"seconds": seconds, "added_mib": (peak - base) / 1024}))
"""


def record(out: Path) -> None:
    protocol = (ROOT / "protocols/demo.yaml").read_text()
    protocol = protocol.replace("times: 3", f"times: {REPETITIONS}")
    source = out.with_suffix(".yaml")
    source.write_text(protocol)
    started = time.perf_counter()
    subprocess.run(
        [sys.executable, "-m", "labrig", "run", str(source), "--sim", "--out", str(out)],
        check=True,
        capture_output=True,
    )
    print(f"recorded {out} in {time.perf_counter() - started:.0f} s", file=sys.stderr)


def measure(path: Path, code: str, repeats: int = 3) -> tuple[float, float]:
    """(median seconds, largest memory added in MiB) over ``repeats`` fresh processes."""
    results = []
    for _ in range(repeats):
        out = subprocess.run(
            [sys.executable, "-c", PROBE, str(path), code],
            check=True,
            capture_output=True,
            text=True,
        ).stdout
        results.append(json.loads(out.splitlines()[-1]))
    seconds = sorted(r["seconds"] for r in results)[len(results) // 2]
    return seconds, max(r["added_mib"] for r in results)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--run", type=Path, help="a recorded run file to read")
    add_write_docs_argument(parser)
    args = parser.parse_args()
    doc = script_doc(["open-run"], args.write_docs)
    with tempfile.TemporaryDirectory() as folder:
        path = args.run or Path(folder) / "thirty_minutes.h5"
        if args.run is None:
            record(path)
        import h5py

        with h5py.File(path, "r") as h5:
            reps = h5["entry/repetitions"]
            rig_min = float((reps["t_end"][-1] - reps["t_start"][0]) / 60)
            samples = sum(
                len(reps[f"rep_{i:02d}/pressure/time"]) for i in range(1, len(reps["status"]) + 1)
            )
        size_mib = path.stat().st_size / 2**20
        rows = []
        for what, code in CASES.items():
            seconds, added = measure(path, code)
            rows.append((what, f"{seconds:.3f}", f"{added:.0f}"))
            print(f"{what}: {seconds:.3f} s, +{added:.0f} MiB", file=sys.stderr)
    table = markdown_table(
        ("reading the run", "time (s, median of 3)", "memory added (MiB, peak)"), rows, right=(1, 2)
    )
    caption = (
        f"The run: {rig_min:.1f} min of rig time, {REPETITIONS} repetitions, "
        f"{samples:,} pressure samples, a {size_mib:.0f} MiB file.\n\n"
    )
    doc.publish("open-run", caption + table)


if __name__ == "__main__":
    main()
