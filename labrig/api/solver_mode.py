"""The model's inner loops as plain Python for the API, as the command line chooses.

A notebook solves one actuator at a time (a run's comparison, ``actuator(...).path()``):
a few hundred calls of the solver's inner loops, ~15 ms as plain Python against ~0.5 s
to load numba's compiled code, or 20-40 s to compile it on a fresh install
(``labrig.model.actuator.jit``). The mode is fixed when that module is first imported,
so it is chosen here, before that import, unless the user chose (``LABRIG_JIT``) or the
model is already loaded. The variable is set only for that import, so commands the
notebook starts (a scan, which compiles) keep their own choice.

So the mode follows what the API's calls cost, not what a notebook happened to import
first: every entry that reaches the model calls ``prefer_plain_python`` before it
imports anything of the model or the analysis (``open_run``, ``open_scan``, ``segment``,
``Actuator.path``), and no module of ``labrig.api`` imports either at its top (the
analysis's package imports its comparison with the model, and with it the solver).
"""

from __future__ import annotations

import importlib
import os
import sys

JIT_MODULE = "labrig.model.actuator.jit"
# jit.MODE_VARIABLE and jit.PYTHON: importing jit to read them would fix the mode
MODE_VARIABLE, PYTHON = "LABRIG_JIT", "python"


def prefer_plain_python() -> None:
    """Import the model's jit switch in plain-Python mode if nothing chose yet."""
    if JIT_MODULE in sys.modules or MODE_VARIABLE in os.environ:
        return
    os.environ[MODE_VARIABLE] = PYTHON
    try:
        importlib.import_module(JIT_MODULE)
    finally:
        del os.environ[MODE_VARIABLE]
