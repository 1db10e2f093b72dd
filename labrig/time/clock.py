"""One clock for every device, the runner and the plant.

Every timestamp in a run comes from the same clock, so samples from the pump, the DAQ
and the camera line up. On the bench that is ``RealClock``, the host's monotonic clock;
in simulation it is ``labrig.time.virtual.VirtualClock``, a discrete-event clock on
which time stands still while any participant works and jumps to the next wake-up
when all of them wait (docs/explanation/virtual-time.md).

The runner is written once against this contract. Besides ``now`` and ``sleep`` it
waits for conditions (``wait_for``) and starts its acquisition loops (``start_thread``)
through the clock, because on a virtual clock those are the moments where time may
move on: a loop started behind the clock's back, or a condition polled with host
sleeps, would let virtual time run while the code that should be observing it works.
"""

from __future__ import annotations

import contextlib
import threading
import time
from collections.abc import Callable, Iterator
from typing import Protocol, runtime_checkable

# How often a RealClock re-evaluates a wait_for condition (host seconds).
REAL_POLL_S = 0.01


@runtime_checkable
class ClockThread(Protocol):
    """A thread started through a clock."""

    name: str

    @property
    def done(self) -> bool:
        """True once the thread's target has returned (or raised)."""
        ...


@runtime_checkable
class Clock(Protocol):
    """A source of time in seconds, shared by everything in a run."""

    def now(self) -> float:
        """Seconds since an arbitrary, fixed origin; never decreases."""
        ...

    def sleep(self, seconds: float) -> None:
        """Block the calling thread for ``seconds`` of this clock's time."""
        ...

    def wait_for(self, predicate: Callable[[], bool], timeout_s: float) -> bool:
        """Block until ``predicate()`` is true or ``timeout_s`` of clock time passed;
        return the predicate's last value. The predicate must be cheap and must not
        block: a virtual clock evaluates it whenever time could move on."""
        ...

    def start_thread(self, target: Callable[[], None], name: str) -> ClockThread:
        """Run ``target`` in a new daemon thread that takes part in this clock's time."""
        ...

    def call_at(self, t_s: float, callback: Callable[[], None]) -> Timer:
        """Call ``callback()`` once, at clock time ``t_s`` (at once if past). Callbacks
        must be short and must not wait on the clock."""
        ...

    def participate(self) -> contextlib.AbstractContextManager[None]:
        """Make the calling thread a participant of the clock for a ``with`` block."""
        ...


@runtime_checkable
class Timer(Protocol):
    def cancel(self) -> None:
        """Do not call the callback (no effect once it has been called)."""
        ...


class _RealThread:
    def __init__(self, target: Callable[[], None], name: str) -> None:
        self.name = name
        self.thread = threading.Thread(target=target, name=name, daemon=True)
        self.thread.start()

    @property
    def done(self) -> bool:
        return not self.thread.is_alive()


class RealClock:
    """The host's monotonic clock, for the real rig: every wait is a real wait."""

    def now(self) -> float:
        return time.monotonic()

    def sleep(self, seconds: float) -> None:
        if seconds > 0:
            time.sleep(seconds)

    def wait_for(self, predicate: Callable[[], bool], timeout_s: float) -> bool:
        deadline = time.monotonic() + timeout_s
        while not (ok := predicate()):
            left = deadline - time.monotonic()
            if left <= 0:
                break
            time.sleep(min(REAL_POLL_S, left))
        return ok

    def start_thread(self, target: Callable[[], None], name: str) -> _RealThread:
        return _RealThread(target, name)

    def call_at(self, t_s: float, callback: Callable[[], None]) -> threading.Timer:
        timer = threading.Timer(max(0.0, t_s - time.monotonic()), callback)
        timer.daemon = True
        timer.start()
        return timer

    @contextlib.contextmanager
    def participate(self) -> Iterator[None]:
        yield


class ScaledClock(RealClock):
    """Host time times ``speed``: for an emulator that serves a program outside this
    process (``labrig pump emulate --speed``), which cannot take part in virtual time.
    Waits are real waits of one ``speed``-th of their length."""

    def __init__(self, speed: float = 1.0, start_s: float = 0.0) -> None:
        if not speed > 0:
            raise ValueError(f"clock speed must be > 0, got {speed!r}")
        self.speed = float(speed)
        self._start_s = float(start_s)
        self._real0 = time.monotonic()

    def now(self) -> float:
        return self._start_s + (time.monotonic() - self._real0) * self.speed

    def sleep(self, seconds: float) -> None:
        super().sleep(seconds / self.speed)

    def wait_for(self, predicate: Callable[[], bool], timeout_s: float) -> bool:
        return super().wait_for(predicate, timeout_s / self.speed)

    def call_at(self, t_s: float, callback: Callable[[], None]) -> threading.Timer:
        timer = threading.Timer(max(0.0, (t_s - self.now()) / self.speed), callback)
        timer.daemon = True
        timer.start()
        return timer
