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


class SpeedGovernor:
    """Runs a simulated clock as fast as the machine allows while keeping every sample.

    The acquisition loops report how long their last period really took in clock time
    against the period they asked for. A loop that falls behind (a camera frame
    skipped, a pump poll late) means the host cannot keep up at this speed: the clock
    slows down. When every loop keeps time, it speeds up again, up to ``max_speed``.
    Decisions are taken at most every ``interval_s`` of host time, from the worst
    report since the last one.
    """

    def __init__(
        self,
        clock: SimulatedClock,
        *,
        min_speed: float = 1.0,
        max_speed: float = 200.0,
        interval_s: float = 0.25,
        late_ratio: float = 1.5,
        on_time_ratio: float = 1.15,
    ) -> None:
        self.clock = clock
        self.min_speed = min_speed
        self.max_speed = max_speed
        self.interval_s = interval_s
        self.late_ratio = late_ratio
        self.on_time_ratio = on_time_ratio
        self._lock = threading.Lock()
        self._worst = 0.0
        self._last_decision = time.monotonic()
        self.slowest_speed = clock.speed

    def report(self, interval_s: float, period_s: float) -> None:
        """A loop asked for ``period_s`` and got ``interval_s`` (both clock time)."""
        if period_s <= 0:
            return
        with self._lock:
            self._worst = max(self._worst, interval_s / period_s)
            now = time.monotonic()
            if now - self._last_decision < self.interval_s:
                return
            worst, self._worst, self._last_decision = self._worst, 0.0, now
            speed = self.clock.speed
            if worst > self.late_ratio:
                speed = max(self.min_speed, speed * 0.7)
            elif worst < self.on_time_ratio:
                speed = min(self.max_speed, speed * 1.1)
            if speed != self.clock.speed:
                self.clock.set_speed(speed)
                self.slowest_speed = min(self.slowest_speed, speed)
