"""Interlocks: conditions that stop the pump, whatever the main loop is doing.

After bluesky's suspenders: one tiny base class and a few small subclasses, each
testable alone. Each interlock looks at one kind of reading and returns the reason it
trips, or None. The ``InterlockMonitor`` runs them in the acquisition threads (so a
busy or blocked main loop cannot starve them), and the first trip stops the pump right
there, before anything else happens. The monitor is also checked before a run starts:
a condition that is already true refuses the start.
"""

from __future__ import annotations

import math
import threading
from collections import deque
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
    """Trips when any sample exceeds the limit (an over-range reading counts, but not one
    the driver flags as a cut wire: no pressure leaps from below the limit to above the
    sensor's output band in one sample); the reason names the first sample above it,
    the moment the limit was passed."""

    max_pressure_kpa: float

    def check_pressure(self, block: PressureBlock) -> str | None:
        above = np.flatnonzero(block.pressure_kpa > self.max_pressure_kpa)
        if len(above) == 0:
            return None
        first = int(above[0])
        if block.wire_open is not None and block.wire_open[first]:
            return None  # a cut wire, not a pressure: ``PressureSignal`` names it
        return (
            f"pressure {block.pressure_kpa[first]:.1f} kPa above the limit "
            f"{self.max_pressure_kpa:g} kPa at t = {block.t_s[first]:.2f} s"
        )


class PressureSignal(Interlock):
    """Trips on a sample that is no pressure reading: not a number (the sensor's supply
    lost: 0/0), above the sensor's output band (a cut output wire, which the rig's
    pull-up holds there: NAMUR NE 43's rule that a broken wire reads outside the
    measuring band), or flagged beyond the sensor's or the ADC's range (an output
    shorted to ground reads -4.4 kPa). A sensor dead that way reads low or out of band,
    never as a pressure, so the ceiling alone would let the pump infuse into it."""

    outcome = "faulted"

    def check_pressure(self, block: PressureBlock) -> str | None:
        if block.all_good:
            return None
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
        if block.wire_open is not None and block.wire_open[first]:
            return (
                f"pressure sensor wire open at t = {t_s:.2f} s: the reading "
                f"{p[first]:.1f} kPa is above the sensor's output band, where the pull-up "
                "holds a cut output wire; check the sensor's output wire and connector"
            )
        return (
            f"pressure reading {p[first]:.1f} kPa at t = {t_s:.2f} s is outside the "
            "sensor's range (an output shorted to ground reads -4.4 kPa: check the "
            "sensor's wires)"
        )


# A frozen reading: the same number sample after sample for this long (and this many
# samples), judged only on a signal whose noise dithered the converter over the second
# before: its sample noise, from the second differences (which a smooth pressure leaves
# near 0), at least FROZEN_NOISE_KPA, 0.65 of a 13-bit RSE step of 0.054 kPa (a quiet
# sensor flickering between two codes shows at most half a step)
# (docs/reference/interlocks.md).
FROZEN_S = 0.3
FROZEN_MIN_SAMPLES = 30
FROZEN_ARMING_S = 1.0
FROZEN_NOISE_KPA = 0.035
# the history a verdict needs: the run's minimum and the second before it, and a second
# to spare
FROZEN_WINDOW_S = FROZEN_ARMING_S + FROZEN_S + 1.0


class PressureFrozen(Interlock):
    """Trips when a reading that was dithering stops changing at all: a live input with
    noise of most of a converter step or more never repeats one number for ``FROZEN_S``
    (a quiet one does, on a flat pressure, and is never judged). The DAQ's buffer or the
    driver repeating one block is the cause.

    Each block extends the current run of one number (its first sample's time and its
    length) and adds to the window of history judged (the run and the second before
    it): the window is searched for the run and its noise measured only once the run is
    long enough to trip, which a dithering signal's never is."""

    outcome = "faulted"

    def __init__(self) -> None:
        # the finite samples of the window, a block at a time (a block leaves it whole,
        # once its newest sample is older than the window)
        self._blocks: deque[tuple[np.ndarray, np.ndarray]] = deque()
        self._last_kpa = math.nan  # the newest finite sample
        self._run_t0_s = math.nan  # the current run of one number: its first sample
        self._run_n = 0  # and how many samples it has

    def check_pressure(self, block: PressureBlock) -> str | None:
        t, p = block.t_s, block.pressure_kpa
        if not block.all_good:  # else every sample is finite: no copies
            good = np.isfinite(p)
            t, p = t[good], p[good]
        if len(t):
            self._extend_run(t, p)
            self._blocks.append((t, p))
            horizon_s = t[-1] - FROZEN_WINDOW_S
            while self._blocks[0][0][-1] < horizon_s:
                self._blocks.popleft()
        if not self._blocks:
            return None
        newest_s = self._blocks[-1][0][-1]
        # the run within the window is at most the whole run: a run too short to trip
        # cannot trip, and nothing else needs the window
        if newest_s - self._run_t0_s < FROZEN_S or self._run_n < FROZEN_MIN_SAMPLES:
            return None
        return self._judge()

    def _extend_run(self, t: np.ndarray, p: np.ndarray) -> None:
        changed = np.flatnonzero(p[1:] != p[:-1])
        if len(changed):
            first = int(changed[-1]) + 1
            self._run_t0_s, self._run_n = float(t[first]), len(p) - first
        elif p[0] == self._last_kpa:
            self._run_n += len(p)
        else:
            self._run_t0_s, self._run_n = float(t[0]), len(p)
        self._last_kpa = float(p[-1])

    def _judge(self) -> str | None:
        """The run of one number within the window and the noise of the second before
        it (at least ``FROZEN_MIN_SAMPLES`` samples of it in the window)."""
        t = np.concatenate([t for t, _ in self._blocks])
        p = np.concatenate([p for _, p in self._blocks])
        keep = t >= t[-1] - FROZEN_WINDOW_S
        t, p = t[keep], p[keep]
        changed = np.flatnonzero(p[1:] != p[:-1])
        run_start = int(changed[-1]) + 1 if len(changed) else 0
        if t[-1] - t[run_start] < FROZEN_S or len(p) - run_start < FROZEN_MIN_SAMPLES:
            return None
        # the second before the run, and the change into it
        arming = np.flatnonzero(t[:run_start] >= t[run_start] - FROZEN_ARMING_S)
        if len(arming) < FROZEN_MIN_SAMPLES:
            return None
        noise_kpa = float(np.std(np.diff(p[arming[0] : run_start], 2))) / math.sqrt(6)
        if noise_kpa < FROZEN_NOISE_KPA:
            return None
        return (
            f"pressure reading frozen at {p[-1]:.2f} kPa from t = {t[run_start]:.2f} s: "
            f"{len(p) - run_start} samples of one number where the signal had "
            f"{noise_kpa:.3f} kPa of noise the second before; the DAQ or its driver repeats "
            "old data: check the DAQ's USB link"
        )


# The specimen interlock's numbers (docs/reference/interlocks.md measures them). The
# pressure is judged in 0.1 s means: five mains periods at 50 Hz, six at 60 Hz, so hum
# cancels.
SPECIMEN_BIN_S = 0.1
# A burst: in one infusion, after the pressure has reached BURST_ARMED_KPA, its means stay
# below BURST_FLOOR_FRACTION of the infusion's peak over BURST_WINDOW_ML infused (and
# BURST_MIN_BINS means). A snap drops the pressure and it rises again as fluid comes.
BURST_ARMED_KPA = 3.0
BURST_FLOOR_FRACTION = 0.2
BURST_WINDOW_ML = 0.3
BURST_MIN_BINS = 2
# A leak: while the pump withdraws and still counts more than LEAK_COUNTED_ML in the
# specimen, LEAK_SUCTION_SAMPLES samples in a row read below -LEAK_SUCTION_KPA, come
# down to it without a leap of LEAK_MAX_STEP_KPA (a wire shorted to ground leaps to
# -4.4 kPa): the specimen is empty before the count says so. The threshold is above the
# sensor's -2.5 kPa range end, so it is met before a sample is flagged, and below the
# flow's drop at the end of a healthy withdrawal.
LEAK_SUCTION_KPA = 1.0
LEAK_SUCTION_SAMPLES = 10
LEAK_MAX_STEP_KPA = 2.0
LEAK_COUNTED_ML = 0.2


class SpecimenPressure(Interlock):
    """Trips when the specimen loses its pressure or its fluid: a burst or a leak,
    judged from the pressure and the volume alone (no model of the specimen).

    - A burst (or a fitting that came off): while the pump infuses, the pressure falls
      from what it reached in that infusion to near atmosphere and stays there as more
      fluid comes. A snap-through drops it too, but a snap ends on a branch that holds
      pressure and rises again as fluid keeps coming.
    - A leak: the specimen holds less than the pump has put in, so a withdrawal empties
      it before the pump's count reaches zero, and the pump then draws on an empty
      specimen: the pressure falls below atmosphere with volume still counted. A share
      of the flow lost while infusing is not seen before that: without a model it is a
      softer specimen (a refill to the most the specimen held does not meet the first
      inflation's pressure even without a leak: interconnected segments refill on
      another branch, docs/reference/interlocks.md).

    Thread-safe: ``check_pressure`` and ``check_pump`` come from different threads.
    """

    outcome = "faulted"

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._bin = (-1, 0.0, 0)  # the 0.1 s bin being filled: index, sum, count
        self._bins: deque[tuple[float, float]] = deque()  # (start time, mean), not judged
        # this infusion: its polled (time, volume) from the oldest a bin still needs,
        # its start, its peak mean, and its trailing low stretch (start time, volume
        # there, means in it) or None
        self._moves: deque[tuple[float, float]] = deque()
        self._t0_s = 0.0
        self._peak_kpa = 0.0
        self._low: tuple[float, float, int] | None = None
        # while the pump withdraws: since when, and the volume its latest status counts
        self._withdrawing: float | None = None
        self._last_kpa = 0.0  # the latest finite sample
        self._suction_run = 0  # samples in a row below -LEAK_SUCTION_KPA

    def check_pressure(self, block: PressureBlock) -> str | None:
        t, p = block.t_s, block.pressure_kpa
        t_finite, p_finite = t, p
        # a block of good samples (nearly every one) is judged as it is, without copies
        if not block.all_good:
            finite = np.isfinite(p)
            good = finite & ~block.out_of_range
            if not finite.all():
                t_finite, p_finite = t[finite], p[finite]
            if not good.all():
                t, p = t[good], p[good]
        with self._lock:
            if len(t):
                self._add_to_bins(t, p)
            # suction may run past the sensor's low range end: every finite sample
            return self._suction(t_finite, p_finite) or self._burst()

    def check_pump(self, status: PumpStatus, volume_ml: float) -> str | None:
        with self._lock:
            moves = self._moves
            if status.state is not PumpState.INFUSING or (moves and volume_ml < moves[-1][1]):
                moves.clear()
            if status.state is PumpState.INFUSING:
                if not moves:  # a new infusion
                    self._t0_s, self._peak_kpa, self._low = status.t_s, 0.0, None
                moves.append((status.t_s, volume_ml))
            # the volume still counted while withdrawing, None otherwise
            self._withdrawing = volume_ml if status.state is PumpState.WITHDRAWING else None
            return self._burst()

    def _add_to_bins(self, t: np.ndarray, p: np.ndarray) -> None:
        k = np.floor(t / SPECIMEN_BIN_S).astype(np.int64)
        index, total, count = self._bin
        # the block's stretches of one bin (two or three a block): where k changes
        starts = [0, *(np.flatnonzero(k[1:] != k[:-1]) + 1).tolist()]
        ends = [*starts[1:], len(k)]
        for key, first, last in zip(k[starts].tolist(), starts, ends, strict=True):
            if key != index:
                if count:
                    self._bins.append((index * SPECIMEN_BIN_S, total / count))
                index, total, count = key, 0.0, 0
            total += float(p[first:last].sum())
            count += last - first
        self._bin = (index, total, count)

    def _suction(self, t: np.ndarray, p: np.ndarray) -> str | None:
        """Samples below atmosphere while withdrawing with volume still counted."""
        withdrawing = self._withdrawing
        counted = withdrawing is not None and withdrawing > LEAK_COUNTED_ML
        if counted and len(p) == 0:
            return None  # nothing to judge: a run below atmosphere goes on
        # a sample at or above -LEAK_SUCTION_KPA only ends a run: the samples before the
        # first one below it (all of them, in almost every block) are judged at once
        below = np.flatnonzero(p < -LEAK_SUCTION_KPA) if counted else []
        if len(below) == 0:
            self._suction_run = 0
            self._last_kpa = float(p[-1]) if len(p) else self._last_kpa
            return None
        first = int(below[0])
        if first > 0:
            self._suction_run, self._last_kpa = 0, float(p[first - 1])
        for t_s, p_kpa in zip(t[first:].tolist(), p[first:].tolist(), strict=True):
            previous, self._last_kpa = self._last_kpa, p_kpa
            if p_kpa >= -LEAK_SUCTION_KPA:
                self._suction_run = 0
            elif self._suction_run or (
                # crossing down from atmosphere, not a leap nor a reading already low
                previous >= -LEAK_SUCTION_KPA and previous - p_kpa < LEAK_MAX_STEP_KPA
            ):
                self._suction_run += 1
                if self._suction_run >= LEAK_SUCTION_SAMPLES:
                    return (
                        f"the specimen leaks: withdrawing, the pressure fell to {p_kpa:.1f} "
                        f"kPa below atmosphere at t = {t_s:.2f} s with {withdrawing:.2f} "
                        "mL still counted in it: it held less than the pump has put in; "
                        "check the fittings and the specimen for a leak"
                    )
        return None

    def _burst(self) -> str | None:
        """Judge each full bin this infusion's polls cover, in order, once."""
        moves, bins = self._moves, self._bins
        if not moves:
            bins.clear()  # nothing infused: nothing to judge
            return None
        while bins and bins[0][0] + SPECIMEN_BIN_S <= moves[-1][0]:
            t_s, mean_kpa = bins.popleft()
            if t_s < self._t0_s:
                continue
            floor_kpa = BURST_FLOOR_FRACTION * self._peak_kpa
            if self._peak_kpa < BURST_ARMED_KPA or mean_kpa >= floor_kpa:
                self._peak_kpa = max(self._peak_kpa, mean_kpa)
                self._low = None
                continue
            if self._low is None:
                self._low = (t_s, self._volume_at(t_s), 0)
            low_s, low_ml, n_low = self._low
            self._low = (low_s, low_ml, n_low + 1)
            end_s = t_s + SPECIMEN_BIN_S
            infused_ml = self._volume_at(end_s) - low_ml
            if n_low + 1 >= BURST_MIN_BINS and infused_ml >= BURST_WINDOW_ML:
                return (
                    f"the specimen lost pressure: it fell from {self._peak_kpa:.1f} kPa to "
                    f"{mean_kpa:.1f} kPa at {low_ml:.2f} mL and stayed below "
                    f"{floor_kpa:.1f} kPa over {infused_ml:.2f} mL infused (t = {low_s:.2f} "
                    f"to {end_s:.2f} s): a burst or a fitting that came off; check the "
                    "specimen and its connections"
                )
        # polls before the oldest bin still to judge (or the one being filled) are no
        # longer needed
        oldest_s = bins[0][0] if bins else self._bin[0] * SPECIMEN_BIN_S
        while len(moves) > 1 and moves[1][0] <= oldest_s:
            moves.popleft()
        return None

    def _volume_at(self, t_s: float) -> float:
        """The infused volume at ``t_s``, between this infusion's polls."""
        times = [t for t, _ in self._moves]
        return float(np.interp(t_s, times, [v for _, v in self._moves]))


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
