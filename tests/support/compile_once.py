"""numba's compiles of one test run, each function compiled by one worker: the others
wait for it and load what it wrote to numba's cache.

On an empty cache (a fresh clone) the first call of a compiled function in a process
compiles it, and the suite's workers reach the same functions at once: the analysis of
every simulated run calls the solver's kernels (``find_fold``, ``settle_flow``, the
curve tables), so two or three workers compiled the same kernels side by side, 35 s of
CPU each, beside the compiled path's own compile (tests/conftest.py). Here every
compile a test starts in a worker, or a load from the cache, goes through a lock file
of its function, shared by the run's workers; numba looks in its cache again once the
lock is taken, so the second worker loads what the first compiled. Per function, not
one lock for all: workers that need different functions still compile them side by
side. A compile within a compile (a callee typed for its caller) takes no lock of its
own: a worker holds one lock at a time, so no two can wait for each other.

The compiled code is numba's as ever; only who compiles it changes. The processes the
tests start (commands, a scan's workers) compile as they always do.
"""

from __future__ import annotations

import contextlib
from collections.abc import Iterator
from pathlib import Path


def install(folder: Path) -> None:
    """Every top-level compile of this process behind its function's lock file in
    ``folder`` (a folder the run's workers share)."""
    from numba.core.compiler_lock import global_compiler_lock
    from numba.core.dispatcher import Dispatcher

    original = Dispatcher.compile
    nested = [0]  # read and written under numba's compiler lock only

    def compile(self, sig):
        with global_compiler_lock:  # numba's own order: this lock, then the file's
            if nested[0]:
                return original(self, sig)
            nested[0] += 1
            try:
                with file_lock(folder / f"{_name(self)}.compile.lock"):
                    return original(self, sig)
            finally:
                nested[0] -= 1

    Dispatcher.compile = compile


def _name(dispatcher) -> str:
    function = dispatcher.py_func
    return f"{function.__module__}.{function.__qualname__}".replace("<", "").replace(">", "")


@contextlib.contextmanager
def file_lock(path: Path) -> Iterator[None]:
    """An exclusive lock on ``path`` between processes; none where the system has no
    fcntl (the workers then compile side by side, as numba does)."""
    try:
        import fcntl
    except ImportError:
        yield
        return
    with open(path, "a") as handle:
        fcntl.flock(handle, fcntl.LOCK_EX)
        yield  # released when the file closes
