"""Pressure and length against supplied volume: alignment, a common grid, the mean.

The pump log gives the net volume in the specimen at its own (slow) poll times; the
pressure (1 kHz) and the length (a few frames per second) are logged at theirs, all on
the rig's one clock. The supplied volume at any sample time is the pump log interpolated
linearly (the pump moves at a constant rate between polls), and the direction of motion
of the pump interval a sample falls in splits a repetition into its inflation (volume
rising) and deflation (volume falling); samples while the pump holds still belong to
neither curve.

The pump starts and stops between two polls, so a straight line between those two
readings would smear the start over a whole poll period: the specimen is still at rest
for part of it, yet those samples would be given volumes up to one poll's worth of
flow (0.2 mL at 60 mL/min). Where the specimen is stiffest, at v = 0, that bends the
first bins of every curve down by a kPa or two. ``with_motion_corners`` puts the start
and the end of each one-way motion back where the constant rate of the motion's inner
polls says they were.

On the grid (step ``step_ml``, from 0), each curve is the mean of its samples per grid
bin, placed at the mean volume of those samples and then interpolated linearly onto the
grid points. Placing the mean at its own volume keeps the curve unbiased however the
samples fall in a bin (2 camera frames per second leave most bins empty, 1 kHz pressure
fills each with hundreds); gaps wider than ``max_gap_ml`` stay empty (NaN) rather than
being bridged by a straight line.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from labrig.arrays import runs_of_true

INFLATE = 1
DEFLATE = -1
PHASES = {INFLATE: "inflate", DEFLATE: "deflate"}
# a pump interval that moves less than this is a hold (pump counters are quantised)
MIN_MOVE_ML = 1e-6


# polls next to a motion's start or end used to estimate its rate there
RATE_POLLS = 5


def with_motion_corners(pump_t_s: np.ndarray, pump_v_ml: np.ndarray):
    """The pump log with a reading added where each one-way motion really started and
    ended (see the module docstring), as ``(time_s, volume_ml)``.

    The first and last intervals of a motion hold its start and its end. The motion's
    rate is the median of its inner intervals' rates; each of the (up to
    ``RATE_POLLS`` + 1) readings nearest the start then says when the motion started
    (its volume moved at that rate), and the median of those is taken, likewise for
    the end. Medians, because a poll whose time stamp came late (a busy computer; a
    fast simulated clock) would otherwise move the corner. A motion too short to have
    a whole poll interval inside it is left as logged.
    """
    pump_t_s = np.asarray(pump_t_s, dtype=float)
    pump_v_ml = np.asarray(pump_v_ml, dtype=float)
    if len(pump_t_s) < 4:
        return pump_t_s, pump_v_ml
    direction = motion_at(0.5 * (pump_t_s[1:] + pump_t_s[:-1]), pump_t_s, pump_v_ml)
    corners = []
    for value in (INFLATE, DEFLATE):
        for first, last in runs_of_true(direction == value):
            inner = slice(first + 1, last + 1)  # readings inside the motion
            if last - first < 2:
                continue
            rate = float(np.median(np.diff(pump_v_ml[inner]) / np.diff(pump_t_s[inner])))
            if value * rate <= 0:
                continue
            for edge, near in (
                (first, slice(first + 1, min(first + 2 + RATE_POLLS, last + 1))),
                (last + 1, slice(max(last - RATE_POLLS, first + 1), last + 1)),
            ):
                moved_s = (pump_v_ml[near] - pump_v_ml[edge]) / rate
                t_corner = float(np.median(pump_t_s[near] - moved_s))
                lo, hi = sorted((pump_t_s[edge], pump_t_s[first + 1 if edge == first else last]))
                if lo < t_corner < hi:
                    corners.append((t_corner, pump_v_ml[edge]))
    if not corners:
        return pump_t_s, pump_v_ml
    t_add, v_add = np.array(corners).T
    order = np.argsort(np.concatenate([pump_t_s, t_add]), kind="stable")
    return np.concatenate([pump_t_s, t_add])[order], np.concatenate([pump_v_ml, v_add])[order]


def pump_path(
    pump_t_s: np.ndarray, pump_v_ml: np.ndarray, before: tuple[float, float] | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """A repetition's pump log as the analysis uses it: the previous repetition's last
    reading (``before``, (time, volume)) put in front when it is older than the log's
    first, then the motions' corners (``with_motion_corners``). The log is split where
    the runner enters the next repetition, which can fall between the last poll at rest
    and the first poll of the next motion: without the reading before it, the start of
    that motion could not be placed (and the first 0.2 mL of the repetition had no
    curve)."""
    pump_t_s = np.asarray(pump_t_s, dtype=float)
    pump_v_ml = np.asarray(pump_v_ml, dtype=float)
    if before is not None and (len(pump_t_s) == 0 or before[0] < pump_t_s[0]):
        pump_t_s = np.concatenate([[before[0]], pump_t_s])
        pump_v_ml = np.concatenate([[before[1]], pump_v_ml])
    return with_motion_corners(pump_t_s, pump_v_ml)


def last_reading(pump_t_s: np.ndarray, pump_v_ml: np.ndarray) -> tuple[float, float] | None:
    """(time, volume) of a pump log's last reading, None for an empty log."""
    return (float(pump_t_s[-1]), float(pump_v_ml[-1])) if len(pump_t_s) else None


def volume_at(t_s: np.ndarray, pump_t_s: np.ndarray, pump_v_ml: np.ndarray) -> np.ndarray:
    """Supplied volume at the sample times, interpolated from the pump log (held
    constant before its first and after its last reading)."""
    return np.interp(t_s, pump_t_s, pump_v_ml)


def motion_at(t_s: np.ndarray, pump_t_s: np.ndarray, pump_v_ml: np.ndarray) -> np.ndarray:
    """+1 (inflating), -1 (deflating) or 0 (holding) for each sample time: the direction
    of the pump interval the sample falls in."""
    if len(pump_t_s) < 2:
        return np.zeros(len(t_s), dtype=int)
    step = np.diff(pump_v_ml)
    direction = np.where(step > MIN_MOVE_ML, INFLATE, np.where(step < -MIN_MOVE_ML, DEFLATE, 0))
    interval = np.searchsorted(pump_t_s, t_s, side="right") - 1
    inside = (interval >= 0) & (interval < len(step))
    out = np.zeros(len(t_s), dtype=int)
    out[inside] = direction[interval[inside]]
    return out


def volume_grid(v_max_ml: float, step_ml: float) -> np.ndarray:
    """Grid points 0, step, 2 step, ... up to the last one at or below v_max_ml."""
    count = int(np.floor(v_max_ml / step_ml + 1e-9)) + 1
    return np.arange(max(count, 1)) * step_ml


def resample(v_ml: np.ndarray, y: np.ndarray, grid_ml: np.ndarray, max_gap_ml: float) -> np.ndarray:
    """y(v) on the grid from scattered samples (see the module docstring).

    A grid point gets the line through the neighbouring bin means around it, provided
    those are at most ``max_gap_ml`` apart. A grid point at either end of the data (its
    bin holds samples, all on one side of it) gets the line through the two outermost
    bin means continued to it, or its own bin's mean if there is no close neighbour.
    """
    out = np.full(len(grid_ml), np.nan)
    keep = np.isfinite(v_ml) & np.isfinite(y)
    v_ml, y = v_ml[keep], y[keep]
    if len(v_ml) == 0 or len(grid_ml) == 0:
        return out
    step = grid_ml[1] - grid_ml[0] if len(grid_ml) > 1 else 1.0
    bins = np.rint((v_ml - grid_ml[0]) / step).astype(int)
    inside = (bins >= 0) & (bins < len(grid_ml))
    bins, v_ml, y = bins[inside], v_ml[inside], y[inside]
    if len(bins) == 0:
        return out
    counts = np.bincount(bins, minlength=len(grid_ml))
    filled = np.flatnonzero(counts)
    v_mean = np.bincount(bins, v_ml, len(grid_ml))[filled] / counts[filled]
    y_mean = np.bincount(bins, y, len(grid_ml))[filled] / counts[filled]
    # between two bin means: linear, unless they are too far apart
    right = np.searchsorted(v_mean, grid_ml, side="left")
    left = right - 1
    between = (left >= 0) & (right < len(v_mean))
    li, ri = left[between], right[between]
    gap = v_mean[ri] - v_mean[li]
    weight = (grid_ml[between] - v_mean[li]) / np.where(gap > 0, gap, 1.0)
    values = y_mean[li] + weight * (y_mean[ri] - y_mean[li])
    values[gap > max_gap_ml] = np.nan
    out[between] = values
    # the first and last grid points with samples in their bins may lie just outside
    # the bin means: continue the line through the two outermost means (if they are
    # close enough), else take the bin's own mean
    for edge, inner in ((0, 1), (len(v_mean) - 1, len(v_mean) - 2)):
        k = filled[edge]
        if np.isfinite(out[k]):
            continue
        if 0 <= inner < len(v_mean) and abs(v_mean[inner] - v_mean[edge]) <= max_gap_ml:
            slope = (y_mean[inner] - y_mean[edge]) / (v_mean[inner] - v_mean[edge])
            out[k] = y_mean[edge] + slope * (grid_ml[k] - v_mean[edge])
        else:
            out[k] = y_mean[edge]
    return out


@dataclass(frozen=True)
class GridCurves:
    """One repetition's curves on the grid, per phase; ``l_mm`` is None without a
    camera. Grid points the repetition never reached hold NaN."""

    p_kpa: dict[int, np.ndarray]
    l_mm: dict[int, np.ndarray] | None


def phase_curves(
    grid_ml: np.ndarray,
    t_s: np.ndarray,
    y: np.ndarray,
    pump_t_s: np.ndarray,
    pump_v_ml: np.ndarray,
    max_gap_ml: float,
) -> dict[int, np.ndarray]:
    """The inflation and deflation curves of one series on the grid."""
    v_ml = volume_at(t_s, pump_t_s, pump_v_ml)
    motion = motion_at(t_s, pump_t_s, pump_v_ml)
    return {
        phase: resample(v_ml[motion == phase], y[motion == phase], grid_ml, max_gap_ml)
        for phase in PHASES
    }


@dataclass(frozen=True)
class MeanCurve:
    """Mean and spread (sample standard deviation, 0 for a single curve) over
    repetitions; NaN wherever any of them has no value."""

    mean: np.ndarray
    std: np.ndarray


def mean_curve(curves: list[np.ndarray]) -> MeanCurve:
    stack = np.vstack(curves)
    complete = np.all(np.isfinite(stack), axis=0)
    mean = np.full(stack.shape[1], np.nan)
    std = np.full(stack.shape[1], np.nan)
    mean[complete] = stack[:, complete].mean(axis=0)
    ddof = 1 if len(curves) > 1 else 0
    std[complete] = stack[:, complete].std(axis=0, ddof=ddof)
    return MeanCurve(mean, std)


def repetitions_to_average(statuses: list[str], average_last: int) -> list[int]:
    """1-based indices of the repetitions the mean is taken over: the last
    ``average_last`` that completed (the paper averages the last 4 of 5); aborted and
    faulted repetitions never enter the mean."""
    complete = [i + 1 for i, status in enumerate(statuses) if status == "complete"]
    return complete[-average_last:] if average_last > 0 else []
