"""One clock for every device, the runner and the plant.

Every timestamp in a run comes from the same clock, so samples from the pump, the DAQ
and the camera line up. On the bench that is the host's monotonic clock; in simulation
it is a virtual clock that runs ``speed`` times faster than real time, so a 20-minute
protocol runs in seconds while every device still sees the same sequence of events
(the DAQ simulator produces one sample per virtual period however late it is read).
"""

from __future__ import annotations

import threading
import time
from typing import Protocol, runtime_checkable


@runtime_checkable
class Clock(Protocol):
    """A source of time in seconds, shared by everything in a run."""

    def now(self) -> float:
        """Seconds since an arbitrary, fixed origin; never decreases."""
        ...

    def sleep(self, seconds: float) -> None:
        """Block the calling thread for ``seconds`` of this clock's time."""
        ...


class RealClock:
    """The host's monotonic clock, for the real rig."""

    def now(self) -> float:
        return time.monotonic()

    def sleep(self, seconds: float) -> None:
        if seconds > 0:
            time.sleep(seconds)


class SimulatedClock:
    """Virtual time running ``speed`` times faster than the host clock.

    Virtual time starts at ``start_s`` when the clock is made. Any number of threads
    may share it: time is a pure function of the host's monotonic clock, so there is no
    scheduler to deadlock and no thread can starve another of time.
    """

    def __init__(self, speed: float = 1.0, start_s: float = 0.0) -> None:
        if not speed > 0:
            raise ValueError(f"clock speed must be > 0, got {speed!r}")
        self.speed = float(speed)
        self._start_s = float(start_s)
        self._real0 = time.monotonic()
        self._lock = threading.Lock()

    def now(self) -> float:
        with self._lock:
            return self._start_s + (time.monotonic() - self._real0) * self.speed

    def sleep(self, seconds: float) -> None:
        if seconds > 0:
            time.sleep(seconds / self.speed)

    def set_speed(self, speed: float) -> None:
        """Change the speed factor without a jump in virtual time."""
        if not speed > 0:
            raise ValueError(f"clock speed must be > 0, got {speed!r}")
        with self._lock:
            real = time.monotonic()
            self._start_s += (real - self._real0) * self.speed
            self._real0 = real
            self.speed = float(speed)
