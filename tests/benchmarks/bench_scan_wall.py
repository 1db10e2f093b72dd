"""Benchmark: where a whole ``labrig model scan`` process spends its wall time, as the first
scan after install (cold: numba's cache and the library's empty) and warm. Prints
numbers; asserts nothing.

Each scan runs ``labrig model scan --n N`` through the console script's own entry in a
fresh process, with the scan's steps timed from inside (wrappers around the functions
that do them): start-up (the interpreter, labrig's and the command's imports, to the
plan), the plan (which reads numba's cache index), the library (its segments' tables),
the solver (numba's import and its machine code loaded, or compiled), compute (the
chunks on the workers, the parent writing each result as it comes) and the summary;
"rest" is what the steps leave of the whole process's wall time, measured from outside.
The ratio is the whole process's wall time over compute's. "compile beside" is numba's
cold compile in the process the scan starts for it beside the library's tabulation
(within "library" and "solver", not added to them); 0 where the solver was cached.

The options, each measured in the same session, in rounds (A, B, C, ... then again), so
that load from other work falls on all of them: ``before`` (the code of ``--before``, a
commit, checked out into a temporary folder: its own ``labrig`` imported first),
``processes`` (the default: a pool of forked workers, one per core), ``one process``
(``--workers 1``: no pool) and ``threads`` (a pool of threads in the scan's process, in
place of the worker processes: the solver's compiled functions hold the GIL, so this
is what threads give without nogil kernels). The scan files of all must hold the same
transitions (checked here, value for value).

Run: python tests/benchmarks/bench_scan_wall.py [--n 3] [--rounds 3] [--cold-rounds 1]
[--before COMMIT] [--write-docs]
"""

import argparse
import json
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import h5py
import numpy as np

from labrig.cli.performance_doc import add_write_docs_argument, markdown_table, script_doc

ROOT = Path(__file__).resolve().parents[2]
STEPS = ("start-up", "plan", "library", "solver", "compute", "summary")

PROBE = """
import json, sys, time
entered = time.time()
import labrig.model.scan.plan as plan
from labrig.cli import main

spans = {}

def timed(owner, name, key):
    real = getattr(owner, name)
    def wrapper(*args, **kwargs):
        started = time.perf_counter()
        try:
            return real(*args, **kwargs)
        finally:
            spans[key] = spans.get(key, 0.0) + time.perf_counter() - started
    setattr(owner, name, wrapper)

def with_threads(library, chunks, sink, *, workers, stop=None):
    from concurrent.futures import ThreadPoolExecutor
    from labrig.model.scan import scan
    for curve in library.curves:
        scan.kernel_of(curve)
    solve = scan._rows_function(library)
    if isinstance(solve, scan._CompiledRows):
        solve.warm()
    with ThreadPoolExecutor(workers) as pool:
        for result in pool.map(lambda c: scan.run_chunk(library, c), chunks):
            sink([result])

real_choose = plan.choose_solver_mode

def choose(*args):
    spans["start-up"] = time.time() - entered
    started = time.perf_counter()
    chosen = real_choose(*args)
    spans["plan"] = time.perf_counter() - started
    # the solver's modules only now: importing them fixes its mode
    import labrig.cli.model_scan as command
    import labrig.model.scan.run as run
    import labrig.model.scan.scan as scan
    if THREADS:
        run.run_chunks = with_threads
    timed(scan, "load_library", "library")
    timed(scan._CompiledRows, "warm", "solver")
    import labrig.model.scan.background_compile as compiling
    if hasattr(compiling, "compile_beside"):  # not in the code of every --before
        beside = compiling.compile_beside

        def compile_beside(*args):
            started = time.perf_counter()
            process = beside(*args)
            wait = process.wait

            def timed_wait(*args):
                waiting = time.perf_counter()
                try:
                    return wait(*args)
                finally:  # its whole compile, and what the scan waited for past the library
                    spans["compile"] = time.perf_counter() - started
                    spans["waited"] = time.perf_counter() - waiting

            process.wait = timed_wait
            return process

        compiling.compile_beside = compile_beside
    timed(run, "run_chunks", "chunks")
    timed(command, "print_summary", "summary")
    return chosen

plan.choose_solver_mode = choose
THREADS = sys.argv[1] == "threads"
try:
    main(sys.argv[2:])
except SystemExit as exited:
    assert not exited.code, exited.code
spans["entered"] = entered
print(json.dumps(spans))
"""


def scan_once(option: str, n: int, out: Path, env: dict, base: Path | None) -> dict:
    """One scan in a fresh process: its steps (s), wall and CPU time."""
    argv = ["model", "scan", "--n", str(n), "--out", str(out)]
    if option == "one process":
        argv += ["--workers", "1"]
    env = dict(env)
    if base is not None:
        env["PYTHONPATH"] = str(base)  # before the editable install's finder
    cpu = resource.getrusage(resource.RUSAGE_CHILDREN)
    started_epoch, started = time.time(), time.perf_counter()
    done = subprocess.run(
        [sys.executable, "-c", PROBE, option, *argv],
        cwd=out.parent,  # not the clone: its labrig would stand first on sys.path
        env=env,
        capture_output=True,
        text=True,
    )
    wall = time.perf_counter() - started
    if done.returncode:
        raise SystemExit(f"{option}: the scan failed:\n{done.stderr[-2000:]}")
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    spans = json.loads(done.stdout.strip().splitlines()[-1])
    spans["start-up"] += spans.pop("entered") - started_epoch
    spans["compute"] = spans.pop("chunks") - spans.get("solver", 0.0)
    spans["solver"] = spans.get("solver", 0.0) + spans.pop("waited", 0.0)
    spans["wall"] = wall
    spans["cpu"] = after.ru_utime + after.ru_stime - cpu.ru_utime - cpu.ru_stime
    spans["load"] = os.getloadavg()[0]
    return spans


def transitions(path: Path) -> dict[str, np.ndarray]:
    """A scan file's rows, failures and segment names."""
    with h5py.File(path) as h5:
        found = {"segments/name": h5["segments/name"][()]}
        for group in ("transitions", "failures"):
            found |= {f"{group}/{name}": h5[group][name][()] for name in h5[group]}
    return found


def same(a: Path, b: Path) -> bool:
    first, second = transitions(a), transitions(b)
    return first.keys() == second.keys() and all(np.array_equal(first[k], second[k]) for k in first)


def checkout(commit: str, folder: Path) -> Path:
    """The package of ``commit`` in ``folder`` (``git archive``)."""
    archive = subprocess.run(
        ["git", "-C", str(ROOT), "archive", commit, "labrig"], check=True, capture_output=True
    ).stdout
    subprocess.run(["tar", "-x", "-C", str(folder)], input=archive, check=True)
    return folder


def row(option: str, runs: list[dict]) -> tuple:
    """The medians over ``runs``; rest and the ratio are each run's own, then their
    median (a median of walls over a median of computes would mix two runs)."""
    for spans in runs:
        spans["rest"] = spans["wall"] - sum(spans.get(step, 0.0) for step in STEPS)
        spans["ratio"] = spans["wall"] / spans["compute"] if spans["compute"] > 0 else 0.0

    def median(key: str) -> float:
        values = sorted(r.get(key, 0.0) for r in runs)
        mid = len(values) // 2
        return values[mid] if len(values) % 2 else (values[mid - 1] + values[mid]) / 2

    loads = [r["load"] for r in runs]
    return (
        option,
        *(f"{median(step):.2f}" for step in STEPS),
        f"{median('compile'):.2f}",
        f"{median('rest'):.2f}",
        f"{median('wall'):.2f}",
        f"{median('cpu'):.2f}",
        f"{median('ratio'):.2f}",
        f"{min(loads):.1f}-{max(loads):.1f}",
    )


HEADER = (
    "option",
    *(f"{step} (s)" for step in STEPS),
    "compile beside (s)",
    "rest (s)",
    "whole process (s)",
    "CPU (s)",
    "whole / compute",
    "load",
)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--n", type=int, default=3)
    parser.add_argument("--rounds", type=int, default=3, help="scans per option (median)")
    parser.add_argument("--before", default=None, help="a commit to measure beside (git)")
    parser.add_argument(
        "--cold-rounds", type=int, default=1, help="first scans per code, on empty caches"
    )
    add_write_docs_argument(parser)
    args = parser.parse_args()
    doc = script_doc(["scan-cold", "scan-wall"], args.write_docs)
    options = (["before"] if args.before else []) + ["processes", "one process", "threads"]
    with tempfile.TemporaryDirectory() as folder:
        folder = Path(folder)
        base = None
        if args.before:
            (folder / "before").mkdir()
            base = checkout(args.before, folder / "before")
        env = {k: v for k, v in os.environ.items() if k != "LABRIG_JIT"}
        env["LABRIG_BACKGROUND_COMPILE"] = "0"
        envs: dict[str, dict] = {}
        runs: dict[str, list[dict]] = {option: [] for option in options}
        colds: dict[str, list[dict]] = {"processes": [], "before": []}
        # the first scans, on empty caches of their own (numba's and the library's), in
        # turns: the code before and after each compile and tabulate as on a fresh install;
        # the last round's caches are then the warm scans'
        for i in range(args.cold_rounds):
            for option in colds if base is not None else ["processes"]:
                caches = {
                    "NUMBA_CACHE_DIR": str(folder / f"numba-{option}-{i}"),
                    "LABRIG_CACHE_DIR": str(folder / f"library-{option}-{i}"),
                }
                code = base if option == "before" else None
                out = folder / f"cold-{option}-{i}.h5"
                colds[option].append(scan_once(option, args.n, out, env | caches, code))
                print(f"{option}, cold: {colds[option][-1]}", file=sys.stderr)
                envs[option] = env | caches
        envs |= {o: envs["processes"] for o in ("one process", "threads")}
        files = {}
        for i in range(args.rounds):
            for option in options:
                out = folder / f"{option.replace(' ', '-')}-{i}.h5"
                runs[option].append(
                    scan_once(
                        option, args.n, out, envs[option], base if option == "before" else None
                    )
                )
                files.setdefault(option, out)
                print(f"{option}: {runs[option][-1]}", file=sys.stderr)
        scanned = [*files.values(), *folder.glob("cold-*.h5")]
        identical = all(same(scanned[0], f) for f in scanned if f.exists())
    table = markdown_table(
        HEADER, [row(o, r) for o, r in runs.items()], right=tuple(range(1, len(HEADER)))
    )
    said = (
        f"`labrig model scan --n {args.n}`, warm, median of {args.rounds}"
        + (f"; before: the code of {args.before}" if args.before else "")
        + f". Transitions of every option's file the same: {'yes' if identical else 'NO'}."
    )
    doc.publish("scan-wall", f"{said}\n\n{table}")
    cold_rows = [
        row(f"{option}, cold, turn {i + 1}", [spans])
        for i in range(args.cold_rounds)
        for option, runs in colds.items()
        if runs
        for spans in runs[i : i + 1]
    ]
    said = (
        f"`labrig model scan --n {args.n}`, the first after install (empty caches of its "
        f"own), {args.cold_rounds} turns"
        + (f"; before: the code of {args.before}" if args.before else "")
        + "."
    )
    cold_table = markdown_table(HEADER, cold_rows, right=tuple(range(1, len(HEADER))))
    doc.publish("scan-cold", f"{said}\n\n{cold_table}")


if __name__ == "__main__":
    main()
