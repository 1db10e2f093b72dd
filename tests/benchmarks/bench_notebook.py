"""Benchmark: a notebook's first model call on a fresh install. Prints numbers; asserts
nothing (tests/api/test_solver_mode.py asserts that nothing is compiled).

Each case runs in a new interpreter with no ``LABRIG_JIT`` set and numba's cache in a
new, empty folder (``NUMBA_CACHE_DIR``), as on a fresh install: the whole process's wall
time (interpreter, imports and the call) and its CPU time (which a busy machine changes
less), the time of ``import labrig`` and the call, whether numba was imported and how
many files numba's cache holds after (what it compiled). The run is
the demo (``protocols/demo.yaml`` on the simulated rig), read with the analysis the
runner stored and, as a live or killed run is read, without one (analysed in memory).

Run: python tests/benchmarks/bench_notebook.py [--repeats 3] [--write-docs]
"""

import argparse
import json
import os
import resource
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from labrig.cli.performance_doc import add_write_docs_argument, markdown_table, script_doc

ROOT = Path(__file__).resolve().parents[2]

# each case: the code timed after `import labrig`; RUN and BARE name the two run files
CASES = {
    "labrig.open_run(demo).comparison (analysis stored)": "labrig.open_run(RUN).comparison",
    "labrig.open_run(demo).comparison (no analysis stored: analysed now)": (
        "labrig.open_run(BARE).comparison"
    ),
    'labrig.actuator("B48-T30", "B50-T20").path()': (
        "labrig.actuator('B48-T30', 'B50-T20').path().transitions"
    ),
    "for scale: import labrig and nothing else": "pass",
}

PROBE = """
import json, sys, time
started = time.perf_counter()
import labrig
RUN, BARE = sys.argv[1], sys.argv[2]
exec(sys.argv[3])
print(json.dumps({"call_s": time.perf_counter() - started, "numba": "numba" in sys.modules}))
"""


def record(folder: Path) -> tuple[Path, Path]:
    """The demo run recorded on the simulated rig, and a copy without its analysis."""
    run, bare = folder / "demo.h5", folder / "demo-bare.h5"
    subprocess.run(
        [
            sys.executable,
            "-m",
            "labrig",
            "run",
            ROOT / "protocols/demo.yaml",
            "--sim",
            "--out",
            run,
        ],
        check=True,
        capture_output=True,
    )
    shutil.copyfile(run, bare)
    import h5py

    with h5py.File(bare, "a") as h5:
        del h5["entry/analysis"]
    return run, bare


def fresh_process(code: str, run: Path, bare: Path) -> dict:
    """One case in a new interpreter with an empty numba cache."""
    with tempfile.TemporaryDirectory() as cache:
        env = {k: v for k, v in os.environ.items() if k != "LABRIG_JIT"}
        env["NUMBA_CACHE_DIR"] = cache
        cpu = resource.getrusage(resource.RUSAGE_CHILDREN)
        started = time.perf_counter()
        out = subprocess.run(
            [sys.executable, "-c", PROBE, str(run), str(bare), code],
            check=True,
            capture_output=True,
            text=True,
            env=env,
        ).stdout
        result = json.loads(out.splitlines()[-1])
        result["wall_s"] = time.perf_counter() - started
        after = resource.getrusage(resource.RUSAGE_CHILDREN)
        result["cpu_s"] = after.ru_utime + after.ru_stime - cpu.ru_utime - cpu.ru_stime
        result["compiled"] = sum(1 for p in Path(cache).rglob("*") if p.is_file())
    return result


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=3, help="fresh processes per case")
    add_write_docs_argument(parser)
    args = parser.parse_args()
    doc = script_doc(["notebook"], args.write_docs)
    rows = []
    with tempfile.TemporaryDirectory() as folder:
        run, bare = record(Path(folder))
        for what, code in CASES.items():
            results = [fresh_process(code, run, bare) for _ in range(args.repeats)]
            middle = len(results) // 2
            wall = sorted(r["wall_s"] for r in results)
            call = sorted(r["call_s"] for r in results)
            cpu = sorted(r["cpu_s"] for r in results)
            numba = "yes" if any(r["numba"] for r in results) else "no"
            compiled = max(r["compiled"] for r in results)
            load = os.getloadavg()[0]
            times = (wall[middle], cpu[middle], call[middle])
            rows.append((what, *(f"{t:.2f}" for t in times), numba, compiled, f"{load:.1f}"))
            print(f"{what}: {wall} s wall, numba {numba}, {compiled} files", file=sys.stderr)
    header = (
        "in a fresh process, empty numba cache",
        f"whole process (s, median of {args.repeats})",
        "its CPU (s)",
        "import labrig + the call (s)",
        "numba imported",
        "files compiled",
        "load average after",
    )
    doc.publish("notebook", markdown_table(header, rows, right=(1, 2, 3, 5, 6)))


if __name__ == "__main__":
    main()
