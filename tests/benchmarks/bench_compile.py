"""Benchmark: numba's cold compile of the solver, per dispatcher. Prints numbers; asserts
nothing.

In this fresh process with an empty cache (``NUMBA_CACHE_DIR`` set to a new temporary
folder before numba is imported), it runs what the suite and ``labrig model scan``
compile: the compiled path of a pair (``compiled_path_cached`` in tests/conftest.py, a
scan's ``warm``), chunks of pairs, triples and quadruples with deflation (test_jit's),
and the reference path, whose Python calls compiled kernels with its own argument types
(``--no-reference`` leaves it out). Then, per dispatcher that compiled: its signatures
(more than one recompiles its whole call tree), its compile time with its callees'
compiles (inclusive) and without (own), in wall seconds; and the process's CPU time.

Run: python tests/benchmarks/bench_compile.py [--no-reference] [--passes] [--write-docs]
"""

import argparse
import os
import resource
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

    def on_start(self, event) -> None:
        self.stack.append([event.data["dispatcher"], time.perf_counter(), 0.0])

    def on_end(self, event) -> None:
        dispatcher, started, children = self.stack.pop()
        elapsed = time.perf_counter() - started
        name = f"{dispatcher.py_func.__module__.rsplit('.', 1)[-1]}.{dispatcher.__name__}"
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
            "compiled pair (the suite's fixture, a scan's warm)",
            lambda: solve_actuator(pair, (0, 1)),
        ),
        (
            "chunks n = 2, 3, 4 with deflation (test_jit)",
            lambda: [run_chunk(small_library(), chunk) for chunk in chunks],
        ),
    ]
    if reference:
        library = small_library()
        combos = [(0, 1), (0, 1, 2), (0, 1, 2, 3)]
        work.append(
            (
                "reference path n = 2, 3, 4 with deflation (path.py)",
                lambda: [scan._reference_rows(library, c, True) for c in combos],
            )
        )
    return work


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--no-reference", action="store_true")
    parser.add_argument("--passes", action="store_true", help="also seconds per compiler pass")
    add_write_docs_argument(parser)
    args = parser.parse_args()
    doc = script_doc(["compile"], args.write_docs)
    os.environ["NUMBA_CACHE_DIR"] = tempfile.mkdtemp(prefix="labrig-numba-cache-")
    os.environ.pop("LABRIG_JIT", None)
    t0 = time.perf_counter()
    import numba
    from numba.core import event

    import labrig.model.scan.scan  # noqa: F401

    print(f"numba {numba.__version__}, cache {os.environ['NUMBA_CACHE_DIR']}")
    steps = [(f"imports (numba {numba.__version__}, labrig)", time.perf_counter() - t0, _cpu_s())]
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
