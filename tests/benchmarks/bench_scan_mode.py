"""Benchmark: the figures a scan plans its solver's mode by (``labrig.model.scan.plan.
SolverCosts``), measured here, beside the ones in the code. Prints numbers; asserts
nothing.

Each figure is taken in a fresh process with ``NUMBA_CACHE_DIR`` pointed at a new
temporary folder: the compile (CPU seconds of the first compiled pair, the compile of a
fresh install), the load (CPU seconds of the same pair in a second process, which finds
the cache, less the pair in plain Python), and milliseconds of CPU per actuator, plain
Python and compiled, for n = 2, 3 and 4 (three samples of ``--sample`` actuators from the
start, a third and two thirds of the 36-segment library's order).

Run: python tests/benchmarks/bench_scan_mode.py [--sample 60]
"""

import argparse
import json
import os
import subprocess
import sys
import tempfile

_MEASURE = """
import json, math, sys, time

started = time.process_time()
from labrig.model.scan.scan import Chunk, ScanLibrary, load_library, run_chunk, solve_actuator
from labrig.model.segments.catalog import analytical_segment

pair = ScanLibrary("pair", tuple(analytical_segment(n) for n in ("B46-T20", "B46-T22")))
solve_actuator(pair, (0, 1))
first_pair_s = time.process_time() - started
library = load_library("analytical")
sample = int(sys.argv[1])
ms = {}
for n in (2, 3, 4):
    total = math.comb(len(library.curves), n)
    cpu = count = 0
    for start in (0, total // 3, 2 * total // 3):
        t = time.process_time()
        run_chunk(library, Chunk(0, start, start + sample, n))
        cpu += time.process_time() - t
        count += sample
    ms[n] = 1000 * cpu / count
print(json.dumps({"first_pair_s": first_pair_s, "ms": ms}))
"""


def _measure(cache: str, mode: str | None, sample: int) -> dict:
    env = {k: v for k, v in os.environ.items() if k != "LABRIG_JIT"}
    env["NUMBA_CACHE_DIR"] = cache
    if mode is not None:
        env["LABRIG_JIT"] = mode
    done = subprocess.run(
        [sys.executable, "-c", _MEASURE, str(sample)],
        env=env,
        check=True,
        capture_output=True,
        text=True,
    )
    return json.loads(done.stdout.strip().splitlines()[-1])


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--sample", type=int, default=60, help="actuators per sample")
    args = parser.parse_args()
    from labrig.model.scan.plan import SolverCosts

    with tempfile.TemporaryDirectory() as cache:
        python = _measure(cache, "python", args.sample)
        cold = _measure(cache, None, args.sample)
        warm = _measure(cache, None, args.sample)
    costs = SolverCosts()
    load_s = warm["first_pair_s"] - python["first_pair_s"]
    print(f"{os.cpu_count()} cores, Python {sys.version.split()[0]}; load {os.getloadavg()[0]:.1f}")
    print("| figure | measured | in SolverCosts |")
    print("|---|---:|---:|")
    print(f"| compile, s of CPU | {cold['first_pair_s']:.1f} | {costs.compile_s:.1f} |")
    print(f"| load, s of CPU | {load_s:.2f} | {costs.load_s:.2f} |")
    for n in ("2", "3", "4"):
        print(f"| n = {n} compiled, ms/actuator | {warm['ms'][n]:.2f} | ", end="")
        print(f"{costs.compiled_ms_per_actuator:.2f} |")
        print(f"| n = {n} Python, ms/actuator | {python['ms'][n]:.2f} | ", end="")
        print(f"{costs.python_ms(int(n)):.2f} |")


if __name__ == "__main__":
    main()
