"""Interlocks: conditions that stop the pump, whatever the main loop is doing.

After bluesky's suspenders: one tiny base class and a few small subclasses, each
testable alone. Each interlock looks at one kind of reading and returns the reason it
trips, or None. The ``InterlockMonitor`` runs them in the acquisition threads (so a
busy or blocked main loop cannot starve them), and the first trip stops the pump right
there, before anything else happens. The monitor is also checked before a run starts:
a condition that is already true refuses the start.
"""

from __future__ import annotations

import threading
from dataclasses import dataclass

import numpy as np

from labrig.rig.devices import PressureBlock, Pump, PumpState, PumpStatus


class Interlock:
    """A condition on one kind of reading. Subclasses override the check they need.

    ``outcome`` is how a run that this interlock stops is marked: "aborted" for a
    limit reached, "faulted" for a device that failed.
    """

    outcome = "aborted"

    def check_pressure(self, block: PressureBlock) -> str | None:
        return None

    def check_pump(self, status: PumpStatus, volume_ml: float) -> str | None:
        """``volume_ml`` is the volume in the specimen (the pump's counters may have
        been cleared since the run started)."""
        return None


@dataclass(frozen=True)
class PressureCeiling(Interlock):
    """Trips when any sample exceeds the limit (an over-range reading counts); the
    reason names the first sample above it, the moment the limit was passed."""

    max_pressure_kpa: float

    def check_pressure(self, block: PressureBlock) -> str | None:
        above = np.flatnonzero(block.pressure_kpa > self.max_pressure_kpa)
        if len(above) == 0:
            return None
        first = int(above[0])
        return (
            f"pressure {block.pressure_kpa[first]:.1f} kPa above the limit "
            f"{self.max_pressure_kpa:g} kPa at t = {block.t_s[first]:.2f} s"
        )


class PressureSignal(Interlock):
    """Trips on a sample that is no pressure reading: not a number (the sensor's supply
    lost: 0/0), or flagged beyond the sensor's or the ADC's range while not above the
    limit (a cut output wire reads -4.4 kPa). A dead sensor reads low, never high, so
    the ceiling alone would let the pump infuse into it."""

    outcome = "faulted"

    def check_pressure(self, block: PressureBlock) -> str | None:
        p = block.pressure_kpa
        bad = np.flatnonzero(~np.isfinite(p) | block.out_of_range)
        if len(bad) == 0:
            return None
        first = int(bad[0])
        t_s = block.t_s[first]
        if not np.isfinite(p[first]):
            return (
                f"pressure signal lost at t = {t_s:.2f} s: the reading is not a number "
                "(check the sensor's supply and its wires)"
            )
        return (
            f"pressure reading {p[first]:.1f} kPa at t = {t_s:.2f} s is outside the "
            "sensor's range (a cut output wire reads -4.4 kPa: check the sensor's wires)"
        )


class PressureStuck(Interlock):
    """Trips when every sample for ``stuck_s`` (and at least ``min_samples``) is the
    same number: a live sensor's noise moves the ADC's last bits, a frozen input does
    not. Only the latest stretch of equal samples is followed, across blocks."""

    outcome = "faulted"

    def __init__(self, stuck_s: float, min_samples: int = 50) -> None:
        self.stuck_s = stuck_s
        self.min_samples = min_samples
        self._value = np.nan
        self._since_s = 0.0
        self._count = 0

    def check_pressure(self, block: PressureBlock) -> str | None:
        p, t = block.pressure_kpa, block.t_s
        if len(p) == 0:
            return None
        changes = np.flatnonzero(p[1:] != p[:-1])
        if len(changes):
            start = int(changes[-1]) + 1
            self._since_s, self._count = float(t[start]), len(p) - start
        elif p[0] == self._value:
            self._count += len(p)
        else:
            self._since_s, self._count = float(t[0]), len(p)
        self._value = float(p[-1])
        stuck_s = float(t[-1]) - self._since_s
        if stuck_s >= self.stuck_s and self._count >= self.min_samples:
            return (
                f"pressure signal stuck at {self._value:.2f} kPa for {stuck_s:.2f} s since "
                f"t = {self._since_s:.2f} s ({self._count} identical samples: a frozen "
                "sensor or input)"
            )
        return None


@dataclass(frozen=True)
class VolumeCeiling(Interlock):
    """Trips when the volume in the specimen exceeds the limit."""

    max_volume_ml: float

    def check_pump(self, status: PumpStatus, volume_ml: float) -> str | None:
        if volume_ml > self.max_volume_ml:
            return (
                f"volume {volume_ml:.2f} mL above the limit {self.max_volume_ml:g} mL "
                f"at t = {status.t_s:.2f} s"
            )
        return None


class PumpStall(Interlock):
    """Trips when the pump reports a stall (it sends nothing by itself: it is polled)."""

    outcome = "faulted"

    def check_pump(self, status: PumpStatus, volume_ml: float) -> str | None:
        if status.state is PumpState.STALLED:
            return f"pump stalled at t = {status.t_s:.2f} s"
        return None


@dataclass(frozen=True)
class Trip:
    reason: str
    kind: str  # "aborted" (an operator or limit stop) or "faulted" (a device fault)


class InterlockMonitor:
    """Evaluates the interlocks and stops the pump on the first trip.

    Thread-safe. ``trip`` may be called from any thread (an acquisition loop, a signal
    handler, the main loop); only the first trip counts, and its pump stop is issued
    in the calling thread before ``trip`` returns.
    """

    def __init__(self, pump: Pump, interlocks: list[Interlock]) -> None:
        self.pump = pump
        self.interlocks = list(interlocks)
        self.volume_offset_ml = 0.0
        self._lock = threading.Lock()
        self._tripped = threading.Event()
        self._trip: Trip | None = None
        self.stop_error: Exception | None = None

    @property
    def tripped(self) -> Trip | None:
        return self._trip

    def wait(self, timeout_s: float) -> bool:
        """Block up to ``timeout_s`` of host time; True once something has tripped."""
        return self._tripped.wait(timeout_s)

    def trip(self, reason: str, kind: str = "aborted") -> bool:
        """Stop the pump and record why. Returns False if already tripped."""
        with self._lock:
            if self._trip is not None:
                return False
            self._trip = Trip(reason, kind)
        try:
            self.pump.stop()
        except Exception as exc:  # the pump may be the thing that failed
            self.stop_error = exc
        self._tripped.set()
        return True

    def specimen_volume_ml(self, status: PumpStatus) -> float:
        """Volume in the specimen: what was there when the counters were last cleared
        (``volume_offset_ml``, kept current by the runner) plus the pump's net count."""
        return self.volume_offset_ml + status.net_volume_ml

    def check_pressure(self, block: PressureBlock) -> None:
        for interlock in self.interlocks:
            reason = interlock.check_pressure(block)
            if reason:
                self.trip(reason, interlock.outcome)
                return

    def check_pump(self, status: PumpStatus, volume_ml: float | None = None) -> None:
        """``volume_ml``: the specimen volume computed together with ``status`` (under
        the caller's lock), since the offset may change once that lock is released."""
        if volume_ml is None:
            volume_ml = self.specimen_volume_ml(status)
        for interlock in self.interlocks:
            reason = interlock.check_pump(status, volume_ml)
            if reason:
                self.trip(reason, interlock.outcome)
                return

    def check_start(self, status: PumpStatus, block: PressureBlock | None) -> str | None:
        """The reason a run must not start, or None: every interlock is evaluated on
        the current readings without tripping (nothing is moving yet)."""
        volume_ml = self.specimen_volume_ml(status)
        for interlock in self.interlocks:
            reason = interlock.check_pump(status, volume_ml)
            if reason is None and block is not None:
                reason = interlock.check_pressure(block)
            if reason:
                return reason
        return None
