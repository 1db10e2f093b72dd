"""``njit``: the solver's inner loops compiled by numba, or run as the plain Python
they are written in; one choice per process, made before the model is imported.

A scan solves thousands of actuators, each making thousands of calls into these loops:
compiled they run 20 times faster, and numba's cache (``cache=True``) keeps the machine
code between runs, beside each module in ``__pycache__`` or, where that folder is not
writable (a system-wide install), in the user's cache folder (numba's own fallback;
``NUMBA_CACHE_DIR`` overrides both). One actuator (``labrig model path``, a dry run's
peak pressure) makes a few hundred calls: as Python they take ~15 ms, while loading the
compiled code from the cache takes ~0.2 s plus ~0.3 s to import numba, and compiling it
on a fresh install 20-40 s. So the console script asks for Python for the commands that
solve one actuator (``labrig.cli``), and a scan for the scans where compiling would not
pay (``labrig.model.scan.plan``: a small one on an empty cache), through the environment
variable ``LABRIG_JIT``: ``python`` runs the plain functions, anything else (the default)
compiles. A user can set it either way. The source is the same in both modes and so
are the results, bit for bit (tests/model/actuator/test_jit.py).

The mode is read once, when this module is first imported: every compiled function may
call only compiled ones, so the modes never mix within a process.

Compile time. A fresh install's first scan compiles ``compiled_path.trace_transitions``
and all it calls. numba types and lowers each compiled function once per signature,
and ``labrig.model.actuator.dispatcher`` has LLVM optimise and compile the whole call
tree once, in the library of the function Python calls (numba's own way compiles every
function's machine code, then again within each caller's, five levels deep here). So
the tree is kept small: no literal specialisations (constants passed between compiled
functions), functions called from one place copied into their caller (``INLINE``), no
Python wrappers for those only compiled code calls (``INTERNAL``), small loops where
numba's general library functions would be typed and lowered for each type
(``labrig.model.actuator.array_loops``), and arrays made by ``np.empty`` alone, its dtype
omitted for float64 and ``np.int64`` for integers: numba compiles a constructor once per
type of its shape and of its dtype argument, and ``np.zeros`` compiles an ``np.empty`` and
a fill of its own besides. ``python
tests/benchmarks/bench_compile.py`` measures it on an empty cache (docs/performance.md,
"Compiling").
"""

from __future__ import annotations

import os
import warnings

MODE_VARIABLE = "LABRIG_JIT"
PYTHON = "python"
# read once: see the module docstring
COMPILED = os.environ.get(MODE_VARIABLE, "numba").strip().lower() != PYTHON
if not COMPILED:
    # numpy warns where its scalars give inf or nan (the 1/k sums at a branch end meet
    # both signs of inf), which the solver expects and the compiled code gives silently
    warnings.filterwarnings("ignore", category=RuntimeWarning, module=r"labrig\.model\.actuator\.")


# The options of a leaf function (one that allocates no array): compiled without
# numba's reference counting. A compiled function takes a reference to every array it
# is passed, with an atomic increment and decrement each, which in the solver's small
# functions costs more than their arithmetic (perf, an n = 4 chunk), and compiling it
# costs code in every call. A leaf only reads arrays its caller holds, so it needs none.
LEAF = {"cache": True, "_nrt": False}

# The option of a function compiled code calls from one place only: numba copies its
# code into its caller's instead of compiling it, with its call tree, on its own (see
# "Compile time" in the module docstring). The same arithmetic in the same order: the
# same bits.
INLINE = {"inline": "always"}
# The options of a function only compiled code calls: no wrappers for calls from Python
# (code numba would otherwise compile, with the callees', for every such function), no
# machine code and no cache of its own (a process loads its callers', which holds it).
INTERNAL = {"no_cpython_wrapper": True, "no_cfunc_wrapper": True}
INTERNAL_LEAF = {**INTERNAL, "_nrt": False}  # a LEAF that only compiled code calls


def njit(**options):
    """numba's ``njit(**options)`` when compiling (with the dispatchers of
    ``labrig.model.actuator.dispatcher``), else the function itself."""
    if not COMPILED:
        return _plain
    from labrig.model.actuator.dispatcher import dispatcher

    return lambda function: dispatcher(function, options)


def _plain(function):
    return function
