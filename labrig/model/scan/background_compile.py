"""The solver compiled into numba's cache by a process of its own at the lowest priority,
after a scan that ran as plain Python because compiling would not have paid for it
(``labrig.model.scan.plan``): the next larger scan then loads the machine code instead of
compiling it before it starts. A scan that compiles first starts one per part of the
solver at once (``compile_beside``): the part it runs its actuators with at its own
priority, which it waits for while it builds its library, and the other at the lowest.

At the lowest priority it takes only the cores nothing else wants; one runs at a time
per compile cache (a lock file in the temporary folder named after the cache), and it
stops at once where the cache holds the solver already. ``LABRIG_BACKGROUND_COMPILE=0``
turns it off (the test suite does: it compiles once, in the foreground, for the tests
that need it).

Run as ``python -m labrig.model.scan.background_compile [--now] [compiled|reference]``
(both parts where none is named), which ``start`` and ``compile_beside`` do.
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

from labrig.model.scan.plan import (
    COMPILED_ENTRIES,
    MODE_VARIABLE,
    REFERENCE_ENTRIES,
    solver_cached,
)

SWITCH_VARIABLE = "LABRIG_BACKGROUND_COMPILE"


NOW = "--now"  # the compile a scan waits for: at its priority, not the lowest

# The parts of the solver a scan loads, each compiled by solving actuators with it (which
# compiles what they call and writes it to numba's cache, or loads it from there):
# the compiled path (``trace_transitions``, all it calls copied into its machine code),
# and the reference path's functions that Python calls (``find_fold``, ``settle_flow``
# and the small kernels), which the scan runs for an actuator the compiled path leaves.
# The segments are cheap to build; any pair, and a triple that flows after its snap,
# compile the same.
COMPILED, REFERENCE = "compiled", "reference"
PARTS = (COMPILED, REFERENCE)
_ENTRIES = {COMPILED: COMPILED_ENTRIES, REFERENCE: REFERENCE_ENTRIES}
_NAMES = ("SI-B46-T20", "SI-B46-T22", "SI-B48-T30")


def start() -> bool:
    """Start the background compile, detached from this process and its terminal;
    False where ``LABRIG_BACKGROUND_COMPILE=0`` forbids it."""
    if os.environ.get(SWITCH_VARIABLE, "").strip() == "0":
        return False
    _spawn(start_new_session=True)  # a Ctrl-C in the terminal is not for it
    return True


def compile_beside(waited: str = COMPILED) -> subprocess.Popen:
    """The compile of the part of the solver a scan runs its actuators with (``waited``,
    one of ``PARTS``: the compiled path for a named library, the reference for measured
    curves) in a process of its own, started now, for a scan that compiles first (an
    empty cache) and waits for it: meanwhile the scan builds its library's tables on the
    other core, and then loads the machine code from the cache (or, where none was
    written, compiles it as before). A process, not a thread: LLVM's work releases the
    GIL call by call, and a thread that waited for it back at every call behind the
    tables' Python made the two together slower than one after the other (256 s against
    140 s, measured at load 8).

    The other part is compiled by a second process at the lowest priority, which the scan
    does not wait for: the compiled path leaves the reference none of the analytical
    library's 7,140 triples, and a worker that needs it before that process has cached
    it compiles what it calls, as before."""
    for part in PARTS:
        if part != waited:
            _spawn(part)  # not --now: at the lowest priority
    return _spawn(NOW, waited)


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


def compile_solver(parts: tuple[str, ...] = PARTS) -> None:
    """Compile ``parts`` of the solver (``PARTS``) into numba's cache, or load them from
    it. In a compiling process only."""
    from labrig.model.scan.scan import ScanLibrary, reference_rows, solve_actuator
    from labrig.model.segments.catalog import analytical_segment

    library = ScanLibrary("warm-up", tuple(analytical_segment(n) for n in _NAMES))
    if COMPILED in parts:
        solve_actuator(library, (0, 1))
    if REFERENCE in parts:
        reference_rows(library, (0, 1, 2), True)


@contextlib.contextmanager
def one_at_a_time(parts: tuple[str, ...] = PARTS) -> Iterator[bool]:
    """True while this process holds the background compile's lock for its compile cache
    and ``parts``, False where another holds it; True without a lock where the system
    has none (not POSIX). The lock is the cache's: two compiles of a part into one
    cache would write the same files twice, while the two parts (which write different
    functions) and compiles into different caches (another install, or
    ``NUMBA_CACHE_DIR`` elsewhere) do not wait for each other."""
    try:
        import fcntl
    except ImportError:
        yield True
        return
    # numba writes beside the sources unless NUMBA_CACHE_DIR says where
    cache = os.environ.get("NUMBA_CACHE_DIR") or str(Path(__file__).resolve().parents[2])
    named = "\0".join((os.path.abspath(cache), *parts))
    key = hashlib.sha256(named.encode()).hexdigest()[:12]
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
    parts = tuple(part for part in PARTS if part in sys.argv[1:]) or PARTS
    with one_at_a_time(parts) as mine:
        if mine and not solver_cached(tuple(e for part in parts for e in _ENTRIES[part])):
            compile_solver(parts)


if __name__ == "__main__":
    main()
