"""numba's CPU dispatcher, shaped so that a cold compile optimises and compiles each
function's code once; imported only by a process that compiles
(``labrig.model.actuator.jit``).

numba compiles every function it is asked for into a code library of its own: typed,
lowered to LLVM IR, optimised and turned into machine code. A caller's library links
in the IR of its callees' libraries and optimises and compiles the whole again, so the
deepest functions of the solver (``find_fold`` under ``_cross`` and ``_snap_from_fold``,
under ``_follow``, under ``trace_transitions``) were optimised and compiled at every
level above them: five times. Three changes make it once, for the same bits (LLVM's
optimisations keep IEEE arithmetic as written; nothing here is fast-math):

- A function that only compiled code calls gets a library that is only linked
  (``LinkOnlyLibrary``): its IR is kept as lowered, with numba's per-function clean-up,
  and optimised and compiled once, within the library of the function Python calls.
- A function that Python calls and compiled code calls too has two dispatchers of the
  same source: the one Python calls (with its wrapper and its cache entry), and its
  internal twin, which compiled callers link (``Dispatcher._numba_type_``). A scan's
  compile of ``trace_transitions`` therefore compiles no machine code for
  ``find_fold`` or ``settle_flow`` on their own; the reference path, which calls them
  from Python, compiles those where it runs.
- Compiled code that calls a function passes no literal types: a function called with a
  constant argument (``_follow(..., INFLATE, ...)``, ``objective(EXCESS_VOLUME, ...)``)
  would be compiled for that constant's literal type (``Literal[int](1)``), a
  specialisation of its own per constant, and of each function it passes it on to.
  Here the callee's types are the plain ones (int64, float64): one compile per function.

``python tests/benchmarks/bench_compile.py`` measures the compile on an empty cache.
"""

from __future__ import annotations

from numba.core import types
from numba.core.codegen import JITCodeLibrary
from numba.core.compiler import Compiler
from numba.core.compiler_lock import require_global_compiler_lock
from numba.core.registry import CPUDispatcher

from labrig.model.actuator.jit import INTERNAL


class Dispatcher(CPUDispatcher):
    """``CPUDispatcher`` typing calls from compiled code on unliteral argument types, and
    standing in compiled code for its internal twin where it has one."""

    twin: Dispatcher | None = None

    def get_call_template(self, args, kws):
        args = tuple(types.unliteral(a) for a in args)
        kws = {k: types.unliteral(v) for k, v in kws.items()}
        return super().get_call_template(args, kws)

    @property
    def _numba_type_(self):
        return types.Dispatcher(self if self.twin is None else self.twin)


def dispatcher(function, options: dict) -> Dispatcher:
    """The dispatcher of ``function`` for ``jit.njit(**options)``: internal where the
    options say so (a library that is only linked), else one for calls from Python
    (numba's cache where ``cache``) with an internal twin for calls from compiled code."""
    options = dict(options)
    cache = options.pop("cache", False)
    targetoptions = {"nopython": True, **options}
    twin = Dispatcher(
        py_func=function,
        locals={},
        targetoptions={**targetoptions, **INTERNAL},
        pipeline_class=LinkOnlyCompiler,
    )
    if all(options.get(k) == v for k, v in INTERNAL.items()):
        return twin
    public = Dispatcher(py_func=function, locals={}, targetoptions=targetoptions)
    public.twin = twin
    if cache:
        public.enable_caching()
    return public


class LinkOnlyLibrary(JITCodeLibrary):
    """The code library of a function only compiled code calls: finalising it links its
    callees' IR into its own and stops there, without the module's optimisation or
    machine code, which its callers' libraries make once for the whole."""

    def finalize(self):
        require_global_compiler_lock()
        self._raise_if_finalized()
        for library in dict.fromkeys(self._linking_libraries):  # once each, in order
            self._reload_init.update(library._reload_init)
            self._final_module.link_in(library._get_module_for_linking(), preserve=True)
        self._finalized = True

    def get_pointer_to_function(self, name):
        """No machine code of its own: 0, as numba gives for a wrapper not built."""
        self._ensure_finalized()
        return 0

    @property
    def codegen(self):
        return _NoEnvironment(self._codegen)


class _NoEnvironment:
    """The code generator, but a function without machine code of its own gets no
    environment pointer set: there is no global of its own to set it in. The copies
    in its callers read it only for object mode and Python objects, which the
    solver has none of (and which the copies loaded from numba's cache never had)."""

    def __init__(self, codegen) -> None:
        self._codegen = codegen

    def set_env(self, env_name, env) -> None:
        pass

    def __getattr__(self, name):
        return getattr(self._codegen, name)


class LinkOnlyCompiler(Compiler):
    """numba's compiler, building a ``LinkOnlyLibrary``."""

    def compile_extra(self, func):
        library = LinkOnlyLibrary(self.state.targetctx.codegen(), func.__qualname__)
        library.enable_object_caching()
        self.state.library = library
        return super().compile_extra(func)
