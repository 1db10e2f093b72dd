"""The solver compiled into numba's cache by a process of its own at the lowest priority,
after a scan that ran as plain Python because compiling would not have paid for it
(``labrig.model.scan.plan``): the next larger scan then loads the machine code instead of
compiling it before it starts. A scan that compiles first starts such a process at once,
at its own priority (``compile_beside``), and builds its library meanwhile.

At the lowest priority it takes only the cores nothing else wants; one runs at a time
per compile cache (a lock file in the temporary folder named after the cache), and it
stops at once where the cache holds the solver already. ``LABRIG_BACKGROUND_COMPILE=0``
turns it off (the test suite does: it compiles once, in the foreground, for the tests
that need it).

Run as ``python -m labrig.model.scan.background_compile [--now]``, which ``start`` and
``compile_beside`` do.
"""

from __future__ import annotations

import contextlib
import hashlib
import os
import subprocess
import sys
import tempfile
from collections.abc import Iterator
from pathlib import Path

from labrig.model.scan.plan import MODE_VARIABLE, solver_cached

SWITCH_VARIABLE = "LABRIG_BACKGROUND_COMPILE"


NOW = "--now"  # the compile a scan waits for: at its priority, not the lowest


def start() -> bool:
    """Start the background compile, detached from this process and its terminal;
    False where ``LABRIG_BACKGROUND_COMPILE=0`` forbids it."""
    if os.environ.get(SWITCH_VARIABLE, "").strip() == "0":
        return False
    _spawn(start_new_session=True)  # a Ctrl-C in the terminal is not for it
    return True


def compile_beside() -> subprocess.Popen:
    """The compile in a process of its own, started now, for a scan that compiles first
    (an empty cache) and waits for it: meanwhile the scan builds its library's tables on
    the other core, and then loads the machine code from the cache (or, where none was
    written, compiles it as before). A process, not a thread: LLVM's work releases the
    GIL call by call, and a thread that waits for it back at every call behind the
    tables' Python made the two together slower than one after the other (256 s against
    140 s, measured at load 8)."""
    return _spawn(NOW)


def _spawn(*args: str, start_new_session: bool = False) -> subprocess.Popen:
    env = {k: v for k, v in os.environ.items() if k != MODE_VARIABLE}  # numba's default
    return subprocess.Popen(
        [sys.executable, "-m", __name__, *args],
        env=env,
        stdin=subprocess.DEVNULL,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
        start_new_session=start_new_session,
    )


def compile_solver() -> None:
    """Solve one pair by the compiled path, which compiles the solver's functions that a
    scan loads (``labrig.model.scan.plan.SOLVER_ENTRIES``, with their callees) and
    writes them to numba's cache, or loads them from it. In a compiling process only."""
    from labrig.model.scan.scan import ScanLibrary, solve_actuator
    from labrig.model.segments.catalog import analytical_segment

    names = ("SI-B46-T20", "SI-B46-T22")  # cheap to build; any pair compiles the same
    solve_actuator(ScanLibrary("warm-up", tuple(analytical_segment(n) for n in names)), (0, 1))


@contextlib.contextmanager
def one_at_a_time() -> Iterator[bool]:
    """True while this process holds the background compile's lock for its compile cache,
    False where another holds it; True without a lock where the system has none (not
    POSIX). The lock is the cache's: two compiles into one cache would write the same
    files twice, while compiles into different caches (another install, or
    ``NUMBA_CACHE_DIR`` elsewhere) do not wait for each other."""
    try:
        import fcntl
    except ImportError:
        yield True
        return
    # numba writes beside the sources unless NUMBA_CACHE_DIR says where
    cache = os.environ.get("NUMBA_CACHE_DIR") or str(Path(__file__).resolve().parents[2])
    key = hashlib.sha256(os.path.abspath(cache).encode()).hexdigest()[:12]
    path = Path(tempfile.gettempdir()) / f"labrig-background-compile-{os.getuid()}-{key}.lock"
    with open(path, "a") as lock:
        try:
            fcntl.flock(lock, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            yield False
            return
        yield True  # released when the file closes


def main() -> None:
    if hasattr(os, "nice") and NOW not in sys.argv[1:]:
        os.nice(19)
    with one_at_a_time() as mine:
        if mine and not solver_cached():
            compile_solver()


if __name__ == "__main__":
    main()
