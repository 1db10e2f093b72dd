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
    against the period they asked for. Decisions are taken at most every
    ``interval_s`` of host time, from the reports since the last one:

    - slow down (x0.7) if a loop that loses data when late (a camera: its frames are
      not buffered) lost a whole period (``lost_ratio``: a frame skipped), or if more
      than ``late_fraction`` of the reports came late (``late_ratio``);
    - speed up (x1.1, up to ``max_speed``) if at most ``slow_fraction`` of them took
      longer than ``on_time_ratio``;
    - else hold.

    Judging by fractions, not by the single worst report: at x20 the 0.2 s loops report
    200 times a second, and a host's scheduling jitter (an HDF5 flush, a collection)
    makes one in 20 a little late and one in a thousand twice late without losing
    anything; the worst of 50 reports held the clock near x15.
    """

    def __init__(
        self,
        clock: SimulatedClock,
        *,
        min_speed: float = 1.0,
        max_speed: float = 200.0,
        interval_s: float = 0.25,
        lost_ratio: float = 2.0,
        late_ratio: float = 1.5,
        late_fraction: float = 0.05,
        on_time_ratio: float = 1.15,
        slow_fraction: float = 0.1,
    ) -> None:
        self.clock = clock
        self.min_speed = min_speed
        self.max_speed = max_speed
        self.interval_s = interval_s
        self.lost_ratio = lost_ratio
        self.late_ratio = late_ratio
        self.late_fraction = late_fraction
        self.on_time_ratio = on_time_ratio
        self.slow_fraction = slow_fraction
        self._lock = threading.Lock()
        self._reports = 0
        self._late = 0
        self._slow = 0
        self._lost = False
        self._last_decision = time.monotonic()
        self.slowest_speed = clock.speed

    def report(self, interval_s: float, period_s: float, late_loses_data: bool = True) -> None:
        """A loop asked for ``period_s`` and got ``interval_s`` (both clock time); a loop
        whose device buffers (a DAQ) or keeps counting (a pump) says
        ``late_loses_data=False``."""
        if period_s <= 0:
            return
        ratio = interval_s / period_s
        with self._lock:
            self._reports += 1
            self._late += ratio > self.late_ratio
            self._slow += ratio > self.on_time_ratio
            self._lost |= late_loses_data and ratio >= self.lost_ratio
            now = time.monotonic()
            if now - self._last_decision < self.interval_s:
                return
            reports, late, slow, lost = self._reports, self._late, self._slow, self._lost
            self._reports = self._late = self._slow = 0
            self._lost = False
            self._last_decision = now
            speed = self.clock.speed
            if lost or late > self.late_fraction * reports:
                speed = max(self.min_speed, speed * 0.7)
            elif slow <= self.slow_fraction * reports:
                speed = min(self.max_speed, speed * 1.1)
            if speed != self.clock.speed:
                self.clock.set_speed(speed)
                self.slowest_speed = min(self.slowest_speed, speed)
