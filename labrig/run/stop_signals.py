"""Every way the operator or the system ends a run goes through one trip.

Ctrl-C, SIGTERM (a service manager, ``kill``), SIGHUP (the terminal or the SSH session
closed) and, on Windows, Ctrl-Break and the console's close, log-off and shut-down
events all become the same request: stop the pump, like any interlock, and finalise
the file with the reason. A second request stops now: the runner then waits for
nothing it can leave behind (the pump is still sent a stop).

A handler does no I/O and raises nothing. Python runs signal handlers in the main
thread between two bytecodes, wherever that thread is: inside a driver call holding
the port's lock, or inside the virtual clock's hand-over, which must never be cut
short. So a handler only records the request and wakes the ``stop requests`` thread,
which trips the interlock monitor from outside the clock (the pump's stop is a serial
exchange: it must not wait for a turn in virtual time, which a blocked participant
may hold). The runner's own waits see the trip or the hurry as they see any other
condition, in every clock mode: paced (``--speed``), holding, or at a prompt.
"""

from __future__ import annotations

import contextlib
import logging
import signal
import sys
import threading
from collections.abc import Callable, Iterator

log = logging.getLogger(__name__)

# The reason each signal gives (stored in the run file, shown at the end).
SIGNAL_REASONS = {
    "SIGINT": "stopped by the operator (Ctrl-C)",
    "SIGTERM": "stopped by SIGTERM (a service manager or kill)",
    "SIGHUP": "stopped: the terminal or SSH session was closed (SIGHUP)",
    "SIGBREAK": "stopped by the operator (Ctrl-Break)",
}
# Windows console events (wincon.h) that end the process once the handler returns.
CONSOLE_EVENTS = {
    2: "stopped: the console window was closed",
    5: "stopped: the user logged off",
    6: "stopped: Windows is shutting down",
}
# Windows ends a process this long after a close event came, handler or not: the
# handler waits for the stop and the file up to a little less.
CONSOLE_CLOSE_GRACE_S = 4.5


class StopRequests:
    """Stop requests from signals and console events, turned into one trip.

    ``on_stop(reason)`` is called from the ``stop requests`` thread for the first
    request; ``count`` says how many came, ``hurry`` that a second one did. The runner
    sets ``finished`` once the file is finalised (a console close waits for it)."""

    def __init__(self, on_stop: Callable[[str], None]) -> None:
        self._on_stop = on_stop
        self.count = 0
        self.hurry = False
        self.finished = threading.Event()
        self._reasons: list[str] = []
        self._wake = threading.Event()
        self._closing = False

    def request(self, reason: str) -> None:
        """Ask for the stop. Safe in a signal handler: no I/O, no lock the interrupted
        thread may hold (the main thread never waits on ``_wake``)."""
        self.count += 1
        if self.count > 1:
            self.hurry = True
        self._reasons.append(reason)
        self._wake.set()

    @contextlib.contextmanager
    def installed(self) -> Iterator[None]:
        """Handlers in place and the stop thread serving for the ``with`` block (from
        the main thread only: Python delivers signals there); the previous handlers
        restored after it."""
        if threading.current_thread() is not threading.main_thread():
            yield
            return
        server = threading.Thread(target=self._serve, name="stop requests", daemon=True)
        server.start()
        restore = [self._install_signal(name) for name in SIGNAL_REASONS]
        restore.append(_install_console_handler(self))
        try:
            yield
        finally:
            for undo in reversed(restore):
                undo()
            self._closing = True
            self._wake.set()
            server.join(timeout=5.0)

    def _install_signal(self, name: str) -> Callable[[], None]:
        signum = getattr(signal, name, None)
        if signum is None:
            return lambda: None  # not on this platform (SIGHUP on Windows, SIGBREAK elsewhere)
        reason = SIGNAL_REASONS[name]
        previous = signal.signal(signum, lambda *_: self.request(reason))
        return lambda: signal.signal(signum, previous)

    def _serve(self) -> None:
        """The first request trips the monitor (the pump's stop is sent from here);
        later ones only hurry the runner."""
        served = 0
        while True:
            self._wake.wait()
            self._wake.clear()
            if served == 0 and self._reasons:
                served = 1
                try:
                    self._on_stop(self._reasons[0])
                except Exception:
                    # the runner's shutdown sends the stop again and reports its fate
                    log.exception("the stop requested by %s failed", self._reasons[0])
            if self._closing:
                return


def _install_console_handler(requests: StopRequests) -> Callable[[], None]:
    """On Windows, closing the console window (or logging off, or shutting down) ends
    the process once the console handler returns: the handler asks for the stop and
    holds the process until the run is finalised. Ctrl-C and Ctrl-Break reach Python's
    own signal handlers, so the handler passes them on."""
    if sys.platform != "win32":
        return lambda: None
    import ctypes
    from ctypes import wintypes

    kernel32 = ctypes.WinDLL("kernel32", use_last_error=True)
    handler_type = ctypes.WINFUNCTYPE(wintypes.BOOL, wintypes.DWORD)

    def on_event(event: int) -> bool:
        reason = CONSOLE_EVENTS.get(event)
        if reason is None:
            return False
        requests.request(reason)
        requests.finished.wait(CONSOLE_CLOSE_GRACE_S)
        return True

    handler = handler_type(on_event)
    if not kernel32.SetConsoleCtrlHandler(handler, True):
        log.warning("the console's close event is not handled (error %d)", ctypes.get_last_error())
        return lambda: None
    return lambda: kernel32.SetConsoleCtrlHandler(handler, False)
