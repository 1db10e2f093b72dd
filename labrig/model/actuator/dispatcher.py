"""numba's CPU dispatcher, but compiled code that calls it passes no literal types;
imported only by a process that compiles (``labrig.model.actuator.jit``).

A compiled function called from compiled code with a constant argument
(``_follow(..., INFLATE, ...)``, ``objective(EXCESS_VOLUME, ...)``,
``pressure_and_slope(tables, 0, w)``) is compiled by numba for that constant's literal
type (``Literal[int](1)``): a specialisation of its own per constant, and of each
function it passes it on to, each compiled with its whole call tree. Measured on a
fresh cache (tests/benchmarks/bench_compile.py): ``_follow`` twice, ``_find_fold`` four
times, ``find_fold`` five, ``bracketed_root`` four, 16 s of the compile's 84 s of CPU.
The values are the same at run time either way; here the callee's types are the plain
ones (int64, float64), one compile per function.
"""

from __future__ import annotations

from numba.core import types
from numba.core.registry import CPUDispatcher


class Dispatcher(CPUDispatcher):
    """``CPUDispatcher`` typing calls from compiled code on unliteral argument types."""

    def get_call_template(self, args, kws):
        args = tuple(types.unliteral(a) for a in args)
        kws = {k: types.unliteral(v) for k, v in kws.items()}
        return super().get_call_template(args, kws)
