"""Interlocks: conditions that stop the pump, whatever the main loop is doing.

After bluesky's suspenders: one tiny base class and a few small subclasses, each
testable alone. Each interlock looks at one kind of reading and returns the reason it
trips, or None. The ``InterlockMonitor`` runs them in the acquisition threads (so a
busy or blocked main loop cannot starve them), and the first trip stops the pump right
there, before anything else happens. The monitor is also checked before a run starts:
a condition that is already true refuses the start.
"""

from __future__ import annotations

import bisect
import math
import threading
from collections import deque
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from labrig.errors import LinkLost
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
    limit (an output shorted to ground reads -4.4 kPa). A sensor dead that way reads
    low, never high, so the ceiling alone would let the pump infuse into it. A cut
    output wire reads in range: ``PressureResponse`` sees it."""

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
            "sensor's range (an output shorted to ground reads -4.4 kPa: check the "
            "sensor's wires)"
        )


# The pressure-response interlock's numbers (docs/reference/interlocks.md derives them).
# The pressure is judged in 0.1 s means: five mains periods at 50 Hz, six at 60 Hz, so
# hum cancels, and a 0.05 kPa sample noise (the USB-6009's 13-bit RSE step) becomes 0.005.
RESPONSE_BIN_S = 0.1
# Over each 1 mL infused the pressure must move by 1 kPa ...
RESPONSE_WINDOW_ML = 1.0
RESPONSE_MIN_CHANGE_KPA = 1.0
# ... wherever the model, shifted by up to 1 mL either way (a real specimen's features
# do not sit exactly where its model's do) and made half as stiff, expects at least that.
RESPONSE_SHIFT_ML = 1.0
RESPONSE_STIFFNESS_FRACTION = 0.5
# the fewest 0.1 s means a judged window holds (a window the pressure did not cover is
# not judged)
RESPONSE_MIN_BINS = 3


class PressureResponse(Interlock):
    """Trips when the pressure does not respond to the volume infused: a sensor whose
    output wire is cut reads the USB-6009's open input, about 1.4 V or 27 kPa, in range
    and noisy, whatever the specimen does, so no range check sees it.

    A flat pressure alone proves nothing: interconnected segments cross long stretches
    (the demo's deflation: 24 kPa from 23 mL down to 7) where fluid moves between them
    at almost constant pressure, and a snap-through's peak is flat to first order. So
    a window is judged only where the specimen's model (``model_v_ml``/``model_p_kpa``:
    its quasi-static inflation) expects the pressure to move: over each
    ``window_ml`` infused, the model's change, taken at the smallest it is for any
    shift of the window by up to ``shift_ml`` and scaled by ``stiffness_fraction``,
    must reach ``min_change_kpa``; the pressure's 0.1 s means must then span at least
    ``min_change_kpa``. Only infusion is judged (withdrawal follows another path).

    Thread-safe: ``check_pressure`` and ``check_pump`` come from different threads.
    """

    outcome = "faulted"

    def __init__(
        self,
        model_v_ml: Sequence[float],
        model_p_kpa: Sequence[float],
        *,
        window_ml: float = RESPONSE_WINDOW_ML,
        min_change_kpa: float = RESPONSE_MIN_CHANGE_KPA,
        shift_ml: float = RESPONSE_SHIFT_ML,
        stiffness_fraction: float = RESPONSE_STIFFNESS_FRACTION,
    ) -> None:
        v = np.asarray(model_v_ml, dtype=float)
        p = np.asarray(model_p_kpa, dtype=float)
        # a snap shows as two points at one volume: the grid takes the later (post-snap)
        keep = np.append(v[1:] > v[:-1], True)
        self._model_v, self._model_p = v[keep], p[keep]
        self.window_ml = float(window_ml)
        self.min_change_kpa = float(min_change_kpa)
        self.stiffness_fraction = float(stiffness_fraction)
        # the shifts on a 0.05 mL grid, the model's own sampling
        self._shifts_ml = np.linspace(-shift_ml, shift_ml, 2 * math.ceil(shift_ml / 0.05) + 1)
        self._lock = threading.Lock()
        self._bin = (-1, 0.0, 0)  # the 0.1 s bin being filled: index, sum, count
        self._bins: deque[tuple[float, float]] = deque()  # (start time, mean) of full bins
        self._moves: list[tuple[float, float]] = []  # (time, volume) of this infusion
        self._judged = 0  # the moves already judged

    @classmethod
    def for_protocol(cls, protocol) -> PressureResponse | None:
        """The interlock for a protocol's specimen, its model up to the volume limit
        (None where it cannot be judged: ``for_specimen``)."""
        from labrig.model.segments.catalog import load_segment

        specimen = protocol.specimen
        return cls.for_specimen(
            [load_segment(spec) for spec in specimen.segments],
            specimen.fluid,
            specimen.length,
            protocol.limits.max_volume_ml,
        )

    @classmethod
    def for_specimen(
        cls, segments: Sequence, fluid: str, length: str, v_max_ml: float
    ) -> PressureResponse | None:
        """The interlock for a specimen of these segments (``SegmentCurve``), or None
        where the pump's volume is not the model's: air compresses (the pump displaces
        more than the segments take in) and a blocked specimen is held off its free path."""
        if fluid != "water" or length != "free":
            return None
        from labrig.model.actuator.prediction import predicted_inflation

        v_ml, p_kpa, _ = predicted_inflation(segments, v_max_ml)
        return cls(v_ml, p_kpa)

    def expected_change_kpa(self, v_from_ml: float, v_to_ml: float) -> float:
        """The smallest pressure change the specimen can show from one volume to the
        other: the model's, at its smallest over the shifts that keep the window within
        the model's volumes, times the stiffness fraction (0 where none does)."""
        v0, v1 = v_from_ml + self._shifts_ml, v_to_ml + self._shifts_ml
        inside = (v0 >= self._model_v[0]) & (v1 <= self._model_v[-1])
        if not inside.any():
            return 0.0
        v0, v1 = v0[inside], v1[inside]
        p0 = np.interp(v0, self._model_v, self._model_p)
        p1 = np.interp(v1, self._model_v, self._model_p)
        return self.stiffness_fraction * float(np.min(np.abs(p1 - p0)))

    def check_pressure(self, block: PressureBlock) -> str | None:
        good = np.isfinite(block.pressure_kpa) & ~block.out_of_range
        t, p = block.t_s[good], block.pressure_kpa[good]
        with self._lock:
            if len(t):
                self._add_to_bins(t, p)
            return self._judge()

    def check_pump(self, status: PumpStatus, volume_ml: float) -> str | None:
        with self._lock:
            moves = self._moves
            if status.state is not PumpState.INFUSING or (moves and volume_ml < moves[-1][1]):
                moves.clear()
                self._judged = 0
            if status.state is PumpState.INFUSING:
                moves.append((status.t_s, volume_ml))
            return self._judge()

    def _add_to_bins(self, t: np.ndarray, p: np.ndarray) -> None:
        k = np.floor(t / RESPONSE_BIN_S).astype(np.int64)
        index, total, count = self._bin
        starts = np.flatnonzero(np.diff(k, prepend=k[0] - 1))
        for first, last in zip(starts, [*starts[1:], len(k)], strict=True):
            if k[first] != index:
                if count:
                    self._bins.append((index * RESPONSE_BIN_S, total / count))
                index, total, count = int(k[first]), 0.0, 0
            total += float(np.sum(p[first:last]))
            count += last - first
        self._bin = (index, total, count)

    def _judge(self) -> str | None:
        """Judge each infusion point the pressure has covered, as the end of a window."""
        covered_s = self._bin[0] * RESPONSE_BIN_S  # every full bin ends by then
        moves = self._moves
        while self._judged < len(moves) and moves[self._judged][0] <= covered_s:
            end = self._judged
            self._judged += 1
            t_end, v_end = moves[end]
            # the latest point a full window before (an infusion's volumes only rise)
            start = bisect.bisect_right(moves, v_end - self.window_ml, hi=end, key=_volume) - 1
            if start < 0:
                continue
            t_start, v_start = moves[start]
            # older points and bins can no longer start a window
            del moves[:start]
            self._judged -= start
            while self._bins and self._bins[0][0] < t_start - RESPONSE_BIN_S:
                self._bins.popleft()
            if self.expected_change_kpa(v_start, v_end) < self.min_change_kpa:
                continue
            means = [p for t, p in self._bins if t >= t_start and t + RESPONSE_BIN_S <= t_end]
            if len(means) < RESPONSE_MIN_BINS:
                continue
            span_kpa = max(means) - min(means)
            if span_kpa < self.min_change_kpa:
                return (
                    f"pressure did not respond to the volume infused: {v_end - v_start:.2f} mL "
                    f"from {v_start:.2f} mL (t = {t_start:.2f} to {t_end:.2f} s) moved it by "
                    f"{span_kpa:.2f} kPa where the specimen's model expects at least "
                    f"{self.min_change_kpa:g}: a cut sensor output wire floats (the "
                    "USB-6009 reads about 27 kPa), or the specimen leaks; check the "
                    "sensor's wires and the specimen's connections"
                )
        return None


def _volume(move: tuple[float, float]) -> float:
    return move[1]


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
    # the reason once the pump's stop is confirmed, when that makes ``reason`` untrue
    # (a lost link, found again: the pump no longer "may still be running")
    reason_if_stopped: str | None = None


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

    def trip(
        self, reason: str, kind: str = "aborted", reason_if_stopped: str | None = None
    ) -> bool:
        """Stop the pump and record why. Returns False if already tripped."""
        with self._lock:
            if self._trip is not None:
                return False
            self._trip = Trip(reason, kind, reason_if_stopped)
        try:
            self.pump.stop()
        except Exception as exc:  # the pump may be the thing that failed
            self.stop_error = exc
        self._tripped.set()
        return True

    def fault(self, exc: Exception, device: str = "") -> bool:
        """Trip on a device's error, named by ``device``; a lost link is recorded as
        found again once the pump's stop is confirmed (only a pump reached again can
        confirm one)."""
        where = f"{device}: " if device else ""
        found = f"{where}{exc.lost}; {exc.found_again}" if isinstance(exc, LinkLost) else None
        return self.trip(f"{where}{exc}", "faulted", found)

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
