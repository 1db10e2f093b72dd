"""Benchmark: numba's cold compile of the solver, per dispatcher. Prints numbers; asserts
nothing.

In this fresh process with an empty cache (``NUMBA_CACHE_DIR`` set to a new temporary
folder before numba is imported), it runs what the suite and ``labrig model scan``
compile: the compiled path of a pair (``compiled_path_cached`` in tests/conftest.py, a
scan's ``warm``), chunks of pairs, triples and quadruples with deflation (test_jit's),
and the reference path, whose Python calls compiled kernels with its own argument types
(``--no-reference`` leaves it out). Then, per dispatcher that compiled: its signatures
(more than one recompiles its whole call tree), its compile time with its callees'
compiles (inclusive) and without (own), in wall seconds, and the functions that called
it (numba's library functions, by which of labrig's); and the process's CPU time.

With ``--levels 1,2,3`` it measures instead LLVM's optimisation level (``NUMBA_OPT``) as a
lever: per level, in a fresh process of its own with an empty cache, the compile of the
scan's solver (wall and CPU) and then the CPU time of the first 2,000 triples of the
analytical library by the compiled code, with the compile's share that is LLVM's
(module passes and machine code) beside; levels in turns, ``--rounds`` times.

With ``--before COMMIT`` it measures the same, at numba's default level, for the code of
that commit (checked out into a temporary folder, imported first) and for this code,
in turns: what a change to the compile gains, on the same machine under the same load.

Run: python tests/benchmarks/bench_compile.py [--no-reference] [--passes] [--write-docs]
     python tests/benchmarks/bench_compile.py --levels 1,2,3 [--rounds 1] [--write-docs]
     python tests/benchmarks/bench_compile.py --before COMMIT [--rounds 1] [--write-docs]
"""

import argparse
import atexit
import hashlib
import json
import os
import resource
import shutil
import subprocess
import sys
import tempfile
import time
from collections import defaultdict
from pathlib import Path

from labrig.cli.performance_doc import add_write_docs_argument, markdown_table, script_doc


def _cpu_s() -> float:
    usage = resource.getrusage(resource.RUSAGE_SELF)
    return usage.ru_utime + usage.ru_stime


class _Compiles:
    """numba's compile events (``numba:compile``, nested for callees): inclusive and
    own seconds per dispatcher, and the signatures each compiled."""

    def __init__(self) -> None:
        self.stack: list[list] = []
        self.inclusive: dict[str, float] = defaultdict(float)
        self.own: dict[str, float] = defaultdict(float)
        self.signatures: dict[str, list[str]] = defaultdict(list)

        self.callers: dict[str, set[str]] = defaultdict(set)

    @staticmethod
    def _name(dispatcher) -> str:
        return f"{dispatcher.py_func.__module__.rsplit('.', 1)[-1]}.{dispatcher.__name__}"

    def on_start(self, event) -> None:
        if self.stack:  # which function's typing asked for it: numba's library's users
            self.callers[self._name(event.data["dispatcher"])].add(self._name(self.stack[-1][0]))
        self.stack.append([event.data["dispatcher"], time.perf_counter(), 0.0])

    def on_end(self, event) -> None:
        dispatcher, started, children = self.stack.pop()
        elapsed = time.perf_counter() - started
        name = self._name(dispatcher)
        self.inclusive[name] += elapsed
        self.own[name] += elapsed - children
        self.signatures[name].append(", ".join(str(a) for a in event.data["args"]))
        if self.stack:
            self.stack[-1][2] += elapsed


class _Passes:
    """Own seconds per compiler pass (``numba:run_pass``), summed over functions."""

    def __init__(self) -> None:
        self.stack: list[list] = []
        self.own: dict[str, float] = defaultdict(float)

    def on_start(self, event) -> None:
        self.stack.append([time.perf_counter(), 0.0])

    def on_end(self, event) -> None:
        started, children = self.stack.pop()
        elapsed = time.perf_counter() - started
        self.own[event.data["name"].split(" [")[0]] += elapsed - children
        if self.stack:
            self.stack[-1][1] += elapsed


def _listener(recorder):
    from numba.core import event

    class Listener(event.Listener):
        def on_start(self, ev):
            recorder.on_start(ev)

        def on_end(self, ev):
            recorder.on_end(ev)

    return Listener()


# (n, first rank, last rank + 1) of test_jit's 8-segment library
CHUNKS = [(2, 0, 28), (3, 0, 20), (4, 0, 12)]


def _workloads(reference: bool) -> list[tuple[str, object]]:
    sys.path.insert(0, str(Path(__file__).parents[1]))
    from support.scan_helpers import small_library

    from labrig.model.scan import scan
    from labrig.model.scan.scan import Chunk, ScanLibrary, run_chunk, solve_actuator
    from labrig.model.segments.catalog import analytical_segment

    names = ("B46-T20", "B46-T22")
    pair = ScanLibrary("warm-up", tuple(analytical_segment(n) for n in names))
    chunks = [Chunk(i, start, stop, n, deflate=True) for i, (n, start, stop) in enumerate(CHUNKS)]
    work = [
        (
            "compile: the compiled path (what a first scan waits for)",
            lambda: solve_actuator(pair, (0, 1)),
        ),
        (
            "compute: chunks n = 2, 3, 4 with deflation (test_jit)",
            lambda: [run_chunk(small_library(), chunk) for chunk in chunks],
        ),
    ]
    if reference:
        library = small_library()
        combos = [(0, 1), (0, 1, 2), (0, 1, 2, 3)]
        work.append(
            (
                "compile: the reference's kernels, after it (path.py, n = 2, 3, 4)",
                lambda: [scan.reference_rows(library, c, True) for c in combos],
            )
        )
    return work


# the triples --levels solves with the compiled code, after the compile
LEVEL_TRIPLES = 2000


def _one_level() -> None:
    """In a process of its own (``NUMBA_OPT`` and an empty ``NUMBA_CACHE_DIR`` set by
    ``_levels``): compile, then solve; one line of JSON."""
    from numba.core import codegen

    llvm = [0.0]

    def counted(cls, name):
        real = getattr(cls, name)

        def wrapper(self, *args, **kwargs):
            started = time.thread_time()
            try:
                return real(self, *args, **kwargs)
            finally:
                llvm[0] += time.thread_time() - started

        setattr(cls, name, wrapper)

    counted(codegen.CPUCodeLibrary, "_optimize_final_module")
    counted(codegen.CPUCodeLibrary, "_optimize_functions")
    counted(codegen.JITCodeLibrary, "_finalize_specific")
    from labrig.model.scan.scan import Chunk, load_library, run_chunk, solve_actuator

    library = load_library(None)
    cpu, wall = _cpu_s(), time.perf_counter()
    solve_actuator(library, (0, 1))
    compiled = {"compile_wall": time.perf_counter() - wall, "compile_cpu": _cpu_s() - cpu}
    cpu = _cpu_s()
    result = run_chunk(library, Chunk(0, 0, LEVEL_TRIPLES, 3))
    compiled |= {"run_cpu": _cpu_s() - cpu, "llvm_cpu": llvm[0], "rows": len(result.actuator)}
    digest = hashlib.sha256(result.actuator.tobytes())
    for column in result.columns.values():
        digest.update(column.tobytes())
    compiled["digest"] = digest.hexdigest()  # the same bits at every level
    print(json.dumps(compiled))


def _span(loads: list[float]) -> str:
    return f"{min(loads):.1f}-{max(loads):.1f}"


def _measured(variants: dict[str, dict], rounds: int) -> dict[str, list[dict]]:
    """``_one_level`` in a fresh process per variant (its extra environment) and round,
    variants in turns, each on an empty cache."""
    found: dict[str, list[dict]] = {name: [] for name in variants}
    for _ in range(rounds):
        for name, extra in variants.items():
            env = dict(os.environ, LABRIG_LEVEL_CHILD="1", **extra)
            env.pop("LABRIG_JIT", None)
            with tempfile.TemporaryDirectory(prefix="labrig-numba-cache-") as cache:
                env["NUMBA_CACHE_DIR"] = cache
                done = subprocess.run(
                    [sys.executable, __file__], env=env, capture_output=True, text=True, check=True
                )
            one = json.loads(done.stdout.strip().splitlines()[-1]) | {"load": os.getloadavg()[0]}
            found[name].append(one)
            print(f"{name}: {one}", file=sys.stderr)
    return found


def _before(commit: str, rounds: int, doc) -> None:
    root = Path(__file__).resolve().parents[2]
    with tempfile.TemporaryDirectory() as folder:
        archive = subprocess.run(
            ["git", "-C", str(root), "archive", commit, "labrig"], check=True, capture_output=True
        ).stdout
        subprocess.run(["tar", "-x", "-C", folder], input=archive, check=True)
        variants = {f"before ({commit})": {"PYTHONPATH": folder}, "this code": {}}
        found = _measured(variants, rounds)

    same, table = _compared(found, "code", next(iter(variants)), "before")
    said = (
        f"Median of {rounds}, in turns, each in a fresh process on an empty cache; the "
        f"transitions the same: {'yes' if same else 'NO'}."
    )
    doc.publish("compile-before", f"{said}\n\n{table}")


def _compared(
    found: dict[str, list[dict]], heading: str, base: str, base_name: str
) -> tuple[bool, str]:
    """Whether every variant gave the same transitions, and the table of their medians,
    with ratios to variant ``base``'s (called ``base_name``)."""

    def median(name: str, key: str) -> float:
        values = sorted(r[key] for r in found[name])
        return values[len(values) // 2]

    same = len({r["digest"] for runs in found.values() for r in runs}) == 1
    rows = [
        (
            name,
            f"{median(name, 'compile_wall'):.1f}",
            f"{median(name, 'compile_cpu'):.1f}",
            f"{median(name, 'llvm_cpu'):.1f}",
            f"{median(name, 'compile_cpu') / median(base, 'compile_cpu'):.2f}",
            f"{median(name, 'run_cpu'):.2f}",
            f"{median(name, 'run_cpu') / median(base, 'run_cpu'):.2f}",
            _span([r["load"] for r in found[name]]),
        )
        for name in found
    ]
    header = (
        heading,
        "compile wall (s)",
        "compile CPU (s)",
        "of which LLVM (s)",
        f"compile / {base_name}",
        f"{LEVEL_TRIPLES:,} triples, CPU (s)",
        f"run / {base_name}",
        "load",
    )
    return same, markdown_table(header, rows, right=range(1, 8))


def _levels(levels: list[str], rounds: int, doc) -> None:
    found = _measured({level: {"NUMBA_OPT": level} for level in levels}, rounds)
    same, table = _compared(found, "NUMBA_OPT", levels[-1], f"level {levels[-1]}")
    said = (
        f"Median of {rounds}, levels in turns; the transitions of every level the same: "
        f"{'yes' if same else 'NO'}."
    )
    doc.publish("compile-levels", f"{said}\n\n{table}")


def main() -> None:
    if os.environ.get("LABRIG_LEVEL_CHILD"):
        _one_level()
        return
    parser = argparse.ArgumentParser()
    parser.add_argument("--no-reference", action="store_true")
    parser.add_argument("--passes", action="store_true", help="also seconds per compiler pass")
    parser.add_argument("--levels", default=None, help="NUMBA_OPT levels to compare: 1,2,3")
    parser.add_argument("--before", default=None, help="a commit to measure beside (git)")
    parser.add_argument("--rounds", type=int, default=1, help="with --levels or --before: turns")
    add_write_docs_argument(parser)
    args = parser.parse_args()
    if args.before:
        _before(args.before, args.rounds, script_doc(["compile-before"], args.write_docs))
        return
    if args.levels:
        _levels(
            args.levels.split(","), args.rounds, script_doc(["compile-levels"], args.write_docs)
        )
        return
    doc = script_doc(["compile"], args.write_docs)
    os.environ["NUMBA_CACHE_DIR"] = tempfile.mkdtemp(prefix="labrig-numba-cache-")
    atexit.register(shutil.rmtree, os.environ["NUMBA_CACHE_DIR"], ignore_errors=True)
    os.environ.pop("LABRIG_JIT", None)
    t0 = time.perf_counter()
    import numba
    from numba.core import event

    import labrig.model.scan.scan  # noqa: F401

    print(f"numba {numba.__version__}, cache {os.environ['NUMBA_CACHE_DIR']}")
    steps = [
        (
            f"start-up: imports (numba {numba.__version__}, labrig)",
            time.perf_counter() - t0,
            _cpu_s(),
        )
    ]
    compiles, passes = _Compiles(), _Passes()
    event.register("numba:compile", _listener(compiles))
    if args.passes:
        event.register("numba:run_pass", _listener(passes))
    for label, run in _workloads(not args.no_reference):
        cpu, wall = _cpu_s(), time.perf_counter()
        run()
        steps.append((label, time.perf_counter() - wall, _cpu_s() - cpu))
    print(f"\n{'dispatcher':40s} {'sigs':>4s} {'incl s':>7s} {'own s':>6s}")
    for name in sorted(compiles.own, key=compiles.own.get, reverse=True):
        sigs = compiles.signatures[name]
        inclusive, own = compiles.inclusive[name], compiles.own[name]
        print(f"{name:40s} {len(sigs):4d} {inclusive:7.2f} {own:6.2f}")
        if compiles.callers[name]:
            print(f"    called by {', '.join(sorted(compiles.callers[name]))}")
        if len(sigs) > 1:
            for sig in sigs:
                print(f"    ({sig})")
    steps.append(("all of numba's compiles (within the above)", sum(compiles.own.values()), None))
    steps.append(("the whole process", time.perf_counter() - t0, _cpu_s()))
    table = [
        (label, f"{wall:.1f}", "" if cpu is None else f"{cpu:.1f}") for label, wall, cpu in steps
    ]
    doc.publish("compile", markdown_table(("step", "wall (s)", "CPU (s)"), table, right={1, 2}))
    if args.passes:
        print("\npasses (own s):")
        for name in sorted(passes.own, key=passes.own.get, reverse=True)[:15]:
            print(f"  {name:40s} {passes.own[name]:6.2f}")


if __name__ == "__main__":
    main()
