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
solve one actuator (``labrig.cli``), through the environment variable ``LABRIG_JIT``:
``python`` runs the plain functions, anything else (the default) compiles. A user can
set it either way. The source is the same in both modes and so are the results, bit for
bit (tests/model/test_jit.py).

The mode is read once, when this module is first imported: every compiled function may
call only compiled ones, so the modes never mix within a process.
"""

from __future__ import annotations

import os

MODE_VARIABLE = "LABRIG_JIT"
PYTHON = "python"
# read once: see the module docstring
COMPILED = os.environ.get(MODE_VARIABLE, "numba").strip().lower() != PYTHON


# The options of a leaf function (one that allocates no array): compiled without
# numba's reference counting. A compiled function takes a reference to every array it
# is passed, with an atomic increment and decrement each, and the solver's tables are
# eleven arrays: in a scan these atomic counts took half the time (perf, an n = 4
# chunk), more than the arithmetic of the small functions they wrapped. A leaf only
# reads arrays its caller holds, so it needs none.
LEAF = {"cache": True, "_nrt": False}


def njit(**options):
    """numba's ``njit(**options)`` when compiling, else the function itself."""
    if not COMPILED:
        return _plain
    from numba import njit as numba_njit

    return numba_njit(**options)


def _plain(function):
    return function
