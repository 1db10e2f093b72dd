"""How a scan runs on this machine: on how many local processes, and whether its solver
is compiled by numba or runs as the plain Python it is written in.

The solver's mode is fixed when ``labrig.model.actuator.jit`` is first imported (one mode
per process, and the workers fork from the scan's process), so ``choose_solver_mode``
decides before anything imports the solver, and this module imports none of it.

Compiling pays for scans, not for every scan. Compiled, an actuator takes ~0.3 ms; as
plain Python ~6 ms for a pair and 10 ms to seconds for more segments. Compiling on a
fresh install costs ~40 s of one core, once: numba keeps the machine code in its cache.
So a small scan on an empty cache (``labrig model scan --n 2``: 630 actuators, ~4 s of
Python on one core) runs as Python, and a large one (n = 3 and up) compiles first (in a
process of its own while the scan builds its library's tables,
``labrig.model.scan.background_compile.compile_beside``); a scan whose compiled code is
already cached loads it (~0.5 s). The figures of
``SolverCosts`` were measured on a 2-core machine (``tests/benchmarks/bench_scan_mode.py``
prints them beside the code's); the choice only needs them right within a factor of
about two.

The scan's results are the same bits in both modes: the same source runs either way.
"""

from __future__ import annotations

import importlib.util
import math
import os
import types
from dataclasses import dataclass
from pathlib import Path

# the environment variable ``labrig.model.actuator.jit`` reads (imported, it would fix
# the mode before the choice) and its value for plain Python
MODE_VARIABLE = "LABRIG_JIT"
PYTHON = "python"

# the most segments an actuator of a scan may have; the 36-segment library gives
# 376,992 actuators at n = 5 and 1.9 million at n = 6
MAX_N = 6

# the named library of the 36 braided segments by their bare names
ANALYTICAL = "analytical"

# The compiled functions whose machine code a scan loads from numba's cache, by the part
# of the solver that runs its actuators (``labrig.model.scan.background_compile.PARTS``
# compiles each): the compiled path, for a named library's; the two largest functions
# the reference path calls from Python, for a measured library's (and for an actuator
# the compiled path leaves to the reference). Each one's cache holds its callees' code.
COMPILED_ENTRIES = (("labrig.model.actuator.compiled_path", "trace_transitions"),)
REFERENCE_ENTRIES = (
    ("labrig.model.actuator.fold_search", "find_fold"),
    ("labrig.model.actuator.rosenbrock_flow", "settle_flow"),
)
SOLVER_ENTRIES = COMPILED_ENTRIES + REFERENCE_ENTRIES


def default_workers() -> int:
    """The cores this process may run on."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # not on Linux
        return os.cpu_count() or 1


@dataclass(frozen=True)
class SolverCosts:
    """What a scan's solver costs, in seconds of one core (see the module docstring)."""

    compile_s: float = 40.0  # a cold compile, beside the library's tables, before the workers
    load_s: float = 0.5  # importing numba and loading the cached machine code
    compiled_ms_per_actuator: float = 0.3
    # plain Python, by segments per actuator, the last for more. A pair settles by an
    # exact root (~6 ms); three segments and more by a flow, which where it does not
    # settle runs its 200,000 steps before it fails the actuator, seconds in Python: a
    # heavy tail (triples of 30 in a row averaged 10-840 ms), so the figure is set high
    python_ms_per_actuator: tuple[tuple[int, float], ...] = ((2, 6.0), (3, 100.0))

    def python_ms(self, n: int) -> float:
        table = self.python_ms_per_actuator
        return next((ms for k, ms in table if k >= n), table[-1][1])


@dataclass(frozen=True)
class SolverPlan:
    """The choice for one scan and why: the wall time each mode is expected to take."""

    compiled: bool
    cached: bool
    python_s: float
    compiled_s: float

    @property
    def compiles_now(self) -> bool:
        """The scan compiles the solver before it starts (an empty or stale cache)."""
        return self.compiled and not self.cached


def plan_solver(
    actuators: int, n: int, workers: int, *, cached: bool, costs: SolverCosts = SolverCosts()
) -> SolverPlan:
    """Compiled or plain Python for a scan of ``actuators`` actuators of ``n`` segments on
    ``workers`` processes, whichever is expected to finish first: the compile (when
    not ``cached``) runs on one core before the workers start, the actuators on all of
    them."""
    share = actuators / max(workers, 1) / 1000.0
    python_s = share * costs.python_ms(n)
    setup_s = costs.load_s + (0.0 if cached else costs.compile_s)
    compiled_s = setup_s + share * costs.compiled_ms_per_actuator
    return SolverPlan(compiled_s < python_s, cached, python_s, compiled_s)


def named_library(spec: str | None) -> tuple[str, tuple[str, ...]] | None:
    """The name and segment names of a named library, or None where ``spec`` names a
    folder of measured curves: ``analytical`` (the default: the 36 braided segments by
    their bare names, the default library's), ``paper``, ``paper-r``, ``calibrated`` and ``si`` (the
    36 of that library, named with its prefix as ``labrig.model.segments.catalog``
    spells them: ``paper:B46-T20``), ``gent``. The one place that knows what each named
    library holds: ``load_library`` builds from it, and the plan counts from it without
    building anything."""
    from labrig.model.segments import catalog

    key = (spec or ANALYTICAL).strip().lower()
    if key == ANALYTICAL or key in catalog.LIBRARIES:
        return key, catalog.library_names(None if key == ANALYTICAL else key)
    if key == "gent":
        from labrig.model.segments.gent import GENT_NAMES

        return key, tuple(sorted(GENT_NAMES))
    return None


def library_size(spec: str | None) -> int:
    """How many segments ``labrig.model.scan.scan.load_library(spec)`` gives, counted
    without building them (0 where it will refuse the spec and say why)."""
    named = named_library(spec)
    if named is not None:
        return len(named[1])
    folder = Path(spec)
    return len(list(folder.glob("*.csv"))) if folder.is_dir() else 0


def solver_cached(entries: tuple[tuple[str, str], ...] = SOLVER_ENTRIES) -> bool:
    """Whether numba's cache holds machine code for every function of ``entries`` that
    this process would load: for this numba, this CPU, the function's current bytecode
    and its source file's current stamp, read from numba's own index by numba's own
    code. False when it cannot tell (numba missing, or its cache's layout changed): the
    scan then plans as for an empty cache, which costs a large scan nothing (it compiles,
    which loads what is cached) and a small one at most its run in Python."""
    try:
        return all(_cached(module, name) for module, name in entries)
    except Exception:  # an unknown numba: plan as if the cache were empty
        return False


def _cached(module: str, name: str) -> bool:
    from numba.core.caching import FunctionCache
    from numba.core.registry import cpu_target

    function = _function_without_import(module, name)
    if function is None:
        return False
    cache = FunctionCache(function)
    codegen = cpu_target.target_context.codegen()
    index = cache._cache_file._load_index()  # {} for another numba or a changed source
    return any(
        cache._index_key(key[0], codegen) == key and Path(cache.cache_path, data).is_file()
        for key, data in index.items()
    )


def _function_without_import(module: str, name: str) -> types.FunctionType | None:
    """The top-level function ``name`` of ``module`` as numba's cache sees it (its
    bytecode, first line, qualified name and file), compiled from the module's source
    without running the module: importing it would fix the solver's mode."""
    spec = importlib.util.find_spec(module)
    if spec is None or spec.origin is None:
        return None
    source = Path(spec.origin)
    code = compile(source.read_bytes(), str(source), "exec", dont_inherit=True)
    for constant in code.co_consts:
        if isinstance(constant, types.CodeType) and constant.co_name == name:
            return types.FunctionType(constant, {"__name__": module})
    return None


def choose_solver_mode(library_spec: str | None, n: int, workers: int | None) -> SolverPlan | None:
    """Plan a local scan's solver and set ``LABRIG_JIT`` for this process (and the
    workers it forks) to match. None, and nothing set, where the choice is made
    already (``LABRIG_JIT`` set by the user, or the solver imported in this process: a
    program, or a test, that runs scans in-process) or where the scan will refuse ``n``.
    A resumed scan is planned by all its actuators, done or not."""
    import sys

    if MODE_VARIABLE in os.environ or "labrig.model.actuator.jit" in sys.modules:
        return None
    segments = library_size(library_spec)
    if not 2 <= n <= min(MAX_N, segments):
        return None  # the scan refuses it, and says why
    actuators = math.comb(segments, n)
    workers = default_workers() if workers is None or workers < 1 else workers
    entries = COMPILED_ENTRIES if named_library(library_spec) else REFERENCE_ENTRIES
    plan = plan_solver(actuators, n, workers, cached=solver_cached(entries))
    if not plan.compiled:
        os.environ[MODE_VARIABLE] = PYTHON
    return plan
