"""Measured segment curves: CSV files in, clean ``SegmentCurve`` out, and back to CSV.

The file holds one row per sample with the header ``volume_ml,pressure_kpa,length_mm``,
the volume supplied from the unpressurised state and strictly increasing. Anything else
is refused with one line naming the file, the line and what is allowed.

A table that already has the segment's shape (at most one peak followed by one valley,
as written by ``write_csv`` or ``labrig library add``) is used as it is. Raw data with
noise is averaged on a volume grid and fitted to the rise-fall-rise shape
(``labrig.model.segments.shape_fit``); its samples are the centres of the fitted blocks. Either
way the pressure is then referred to zero at v = 0 (the unpressurised state is at
atmospheric pressure, so what the curve shows there is a residual sensor offset; a gain
error cannot be seen and stays), and a curve that ends below P_END_KPA is extended along
a straight line with its final slope, so that actuators find every pressure they need
on the table (an actuator's other segments may take it far past what one
segment was measured to).
"""

from __future__ import annotations

import csv
import dataclasses
import functools
import itertools
import math
from pathlib import Path

import numpy as np

from labrig.errors import InputError
from labrig.model.segments.curve import SegmentCurve
from labrig.model.segments.resolution import (
    ROUTE_FITTED,
    ROUTE_TABULATED,
    STEP_PROMINENCE,
    MeasuredImport,
    TableResolution,
    resolution_of,
)
from labrig.model.segments.shape_fit import (
    DIP_NOISE_FACTOR,
    binned_trimmed_means,
    fit_rise_fall_rise,
    monotone_pieces,
    one_minimum_slope_rise,
    smooth_with_shape,
)
from labrig.model.segments.stair_edges import refine_extrema, shows_dip
from labrig.user_files import MAX_TABLE_BYTES, read_text_file

HEADER = ("volume_ml", "pressure_kpa", "length_mm")
MIN_ROWS = 10
# a measured curve has a few thousand rows; from this many on (a raw log, up to the
# 50 MB cap: about 2 million rows) the table is parsed by pandas' C parser
LARGE_TABLE_ROWS = 100_000
MAX_FIRST_VOLUME_ML = 0.5  # the first row must be (close to) the unpressurised state
# no segment's curve reaches a million mL, kPa or mm; numbers beyond (1e308) overflow
# the fit's arithmetic to inf
MAX_MAGNITUDE = 1e6
MAX_BINS = 250
STEEP_NOISE_FACTOR = 10.0
STEEP_WEIGHT_GAIN = 100.0
FOLLOW_SIGMAS = 6.0  # how far a joined peak may stray from the bins' means
JOIN_BINS = 5  # bins a rising branch may give to the falling one next to it
OFFSET_BINS = 4  # bins through which the zero at v = 0 of a fitted curve is found
OFFSET_SIGMAS = 3.0  # an offset is removed when it stands out of its uncertainty so far
P_END_KPA = 300.0
# steps from which a staircase's peak and valley come from its stair edges: below, the
# stair values are within 0.025 kPa of them (a snap within ~0.06 mL), and the edges
# were not checked on the 0.01-0.027 kPa tables other tools write
# (docs/explanation/measured-curves.md)
EDGE_MIN_STEP_KPA = 0.05
MIN_END_SLOPE_KPA_PER_ML = 1.0
EXTENSION_SAMPLES = 8
CORNER_STEPS = 2  # a jump of this many steps between two rows at a plateau is a corner
ROUNDING_SLOPE_FACTOR = 10.0  # slopes between rows known to 10 % (median)
# Bore of the paper's latex tube: the enclosed volume at p = 0 is estimated as
# pi R^2 l(0) when the caller does not know it (it only enters normalisations).
TUBE_RADIUS_MM = 6.35


def read_csv_table(path: Path) -> np.ndarray:
    """The (n, 3) table of a measured-curve CSV, validated: a fault is refused with one
    line naming the file, the line, the column and what is allowed."""
    where = str(path)
    text = read_text_file(path, what="file", max_bytes=MAX_TABLE_BYTES, encoding="utf-8-sig")
    rows = [(n, line) for n, line in enumerate(text.splitlines(), start=1) if line]
    expected = ",".join(HEADER)
    if not rows:
        raise InputError(f"{where}: the file is empty; expected the header {expected} and rows")
    line, header = rows[0][0], next(csv.reader([rows[0][1]]))
    if tuple(field.strip() for field in header) != HEADER:
        # what the line holds is not shown: a mistyped path may name any file
        raise InputError(f"{where}: line {line}: the header must be {expected}")
    data = rows[1:]
    values = _numbers_at_once(data)
    if values is None:
        values = _numbers_row_by_row(data, where)
    _check_volumes_and_lengths(values, [n for n, _ in data], where)
    return values


def _numbers_at_once(data: list[tuple[int, str]]) -> np.ndarray | None:
    """The (n, 3) finite numbers of the data rows parsed at once, or None for any row
    the parser cannot take: ``_numbers_row_by_row`` then names the fault. A file of
    8000 rows is read in 5.7 ms by numpy, 21 ms row by row; from ``LARGE_TABLE_ROWS``
    rows pandas' C parser reads it (2 million rows: 0.7 s, numpy's 3.7 s)."""
    if not data:
        return np.empty((0, 3))
    lines = [text for _, text in data]
    try:
        if len(lines) < LARGE_TABLE_ROWS:
            values = np.loadtxt(lines, delimiter=",", comments=None, ndmin=2)
        else:
            values = _parsed_by_pandas(lines)
    except ValueError:
        return None
    if values.shape != (len(data), 3) or not np.all(np.isfinite(values)):
        return None
    return values


def _parsed_by_pandas(lines: list[str]) -> np.ndarray:
    """The rows as floats, read exactly as Python reads them (``round_trip``)."""
    import io

    import pandas as pd

    # pandas from 3.1 reads every float exactly and deprecates the choice; before it,
    # only the round-trip converter does
    major_minor = tuple(int(part) for part in pd.__version__.split(".")[:2])
    exact = {} if major_minor >= (3, 1) else {"float_precision": "round_trip"}
    try:
        table = pd.read_csv(
            io.StringIO("\n".join(lines)),
            header=None,
            dtype=float,
            engine="c",
            skip_blank_lines=False,
            **exact,
        )
    except (pd.errors.ParserError, pd.errors.EmptyDataError) as exc:
        raise ValueError(str(exc)) from None
    return table.to_numpy()


def _numbers_row_by_row(data: list[tuple[int, str]], where: str) -> np.ndarray:
    """The (n, 3) numbers of the data rows, read as CSV row by row: the first row that
    is not three finite numbers is refused, naming its line and column."""
    expected = ",".join(HEADER)
    values = np.empty((len(data), 3))
    for k, (line, text) in enumerate(data):
        row = next(csv.reader([text]))
        if len(row) != 3:
            raise InputError(
                f"{where}: line {line}: expected 3 values ({expected}), got {len(row)}"
            )
        for col, (name, field) in enumerate(zip(HEADER, row, strict=True)):
            try:
                number = float(field)
            except ValueError:
                # what the cell holds is not shown: a mistyped path may name any file
                raise InputError(
                    f"{where}: line {line}, column {name}: not a number (a decimal number "
                    "such as 12.5 or 1.25e1)"
                ) from None
            if not math.isfinite(number):
                raise InputError(
                    f"{where}: line {line}, column {name}: not a finite number (inf and nan "
                    "are not allowed)"
                )
            values[k, col] = number
    return values


def _check_volumes_and_lengths(values: np.ndarray, lines: list[int], where: str) -> None:
    """The rules on the numbers, the first row that breaks one named by its line: every
    number within MAX_MAGNITUDE, the first volume at the unpressurised state, volumes
    that never decrease, lengths > 0, and enough rows."""
    huge = np.abs(values) > MAX_MAGNITUDE
    if huge.any():
        k, col = np.argwhere(huge)[0]
        raise InputError(
            f"{where}: line {lines[k]}, column {HEADER[col]}: beyond +-{MAX_MAGNITUDE:g} "
            "(mL, kPa, mm): not a segment's curve"
        )
    v, length = values[:, 0], values[:, 2]
    first_volume_bad = len(v) > 0 and not 0 <= v[0] <= MAX_FIRST_VOLUME_ML
    decreasing = np.flatnonzero(np.diff(v) < 0) + 1
    not_positive = np.flatnonzero(length <= 0)
    # (row, rule): a row's rules in the order above
    faults = [(0, 0)] if first_volume_bad else []
    faults += [(int(decreasing[0]), 1)] if len(decreasing) else []
    faults += [(int(not_positive[0]), 2)] if len(not_positive) else []
    if faults:
        k, rule = min(faults)
        line = lines[k]
        if rule == 0:
            raise InputError(
                f"{where}: line {line}: the first volume_ml must be the unpressurised state "
                f"(0 to {MAX_FIRST_VOLUME_ML} mL), got {v[0]:g}"
            )
        if rule == 1:
            raise InputError(
                f"{where}: line {line}: volume_ml {v[k]:g} does not increase "
                f"(previous row {v[k - 1]:g}); rows must be in order of supplied "
                "volume (rows at one volume, written to few decimals, are averaged)"
            )
        raise InputError(f"{where}: line {line}, column length_mm: must be > 0, got {length[k]:g}")
    if len(values) < MIN_ROWS:
        raise InputError(f"{where}: {len(values)} data rows; a curve needs at least {MIN_ROWS}")


def _branch_bounds(v, p) -> list[tuple[int, int]]:
    """The (first, last) rows of each monotone branch of the table (v, p)."""
    return SegmentCurve("raw", v, p, np.ones_like(v), V0_ml=1.0).branch_bounds


def _has_segment_shape(v, p, min_dip_kpa: float = 0.0, bounds=None) -> bool:
    """Rising, or rising to one peak, falling to one valley and rising again, with a dip
    (and a rise after the valley) larger than ``min_dip_kpa``."""
    branches = _branch_bounds(v, p) if bounds is None else bounds
    if len(branches) not in (1, 3) or not p[branches[0][1]] > p[0]:
        return False
    if len(branches) == 1:
        return True
    peak, valley = p[branches[0][1]], p[branches[1][1]]
    return peak - valley > min_dip_kpa and p[-1] - valley > min_dip_kpa


def slopes_resolved(v, p, resolution: TableResolution, bounds) -> bool:
    """Whether a rounded table's rows (plateaus already collapsed to their centres)
    still tell the slope of its falling branch, where an actuator's folds are decided
    (its slopes, -0.3 to -0.6 kPa/mL for the library, are compared with the other
    segments'). Each row's pressure is uncertain by its step or its noise, whichever is
    larger (rows averaged at a repeated volume are off the lattice by more than its
    step). Between two rows the slope is off by about that over dp where each row is
    its own value, or by spacing / dv where rows are centres of plateaus (the centre
    moves v): the smaller of the two, whose median over the branch must be at most
    1 / ROUNDING_SLOPE_FACTOR. A sparse table rounded to 0.1 kPa changes by about one
    step per row there, its slopes off by up to 70 %: it is fitted; a dense staircase's
    plateau centres are exact to a row in tens. Full-precision values are not rounded:
    their noise estimate is the interpolation's own residual (7e-5 kPa at a library
    curve's 0.007 kPa dip), and a noisy table is fitted for its dips anyway."""
    if resolution.step_kpa <= 0 or len(bounds) < 3:
        return True
    error_kpa = max(resolution.step_kpa, resolution.noise_kpa)
    a, b = bounds[1]
    dv, dp = np.diff(v[a : b + 1]), np.abs(np.diff(p[a : b + 1]))
    error = np.minimum(error_kpa / dp, resolution.spacing_ml / dv)
    return float(np.median(error)) <= 1.0 / ROUNDING_SLOPE_FACTOR


def average_repeated_volumes(v, p, length):
    """Rows at one volume as one row, their mean: a log at 1,000 rows/mL whose volume
    was written to two decimals repeats each volume ten times. Returns (v, p, l, rows
    averaged away)."""
    starts = np.flatnonzero(np.r_[True, np.diff(v) > 0])
    if len(starts) == len(v):
        return v, p, length, 0
    counts = np.diff(np.r_[starts, len(v)])
    return (
        v[starts],
        np.add.reduceat(p, starts) / counts,
        np.add.reduceat(length, starts) / counts,
        len(v) - len(starts),
    )


def collapse_plateaus(v, p, length):
    """Each run of rows with equal pressure (a quantised table's plateau) as one row at
    the run's centre, where a rounded monotone curve has the plateau's value; the first
    run keeps its first row (the unpressurised state). Returns (v, p, l, runs merged)."""
    starts = _run_starts(p)
    if len(starts) == len(v):
        return v, p, length, 0
    ends = np.r_[starts[1:], len(v)]
    counts = ends - starts
    v_c = np.add.reduceat(v, starts) / counts
    l_c = np.add.reduceat(length, starts) / counts
    v_c[0], l_c[0] = v[0], length[0]
    return v_c, p[starts], l_c, int(np.sum(counts > 1))


def _run_starts(p) -> np.ndarray:
    """The first row of each run of rows with equal pressure (to float rounding)."""
    scale = max(float(np.max(np.abs(p))), 1.0)
    return np.flatnonzero(np.r_[True, np.abs(np.diff(p)) > 1e-12 * scale])


def keep_corner_rows(v, p, length, step_kpa: float):
    """``collapse_plateaus`` for a staircase, keeping the rows of a corner: where a
    plateau (a run of rows at one value) meets a jump of at least ``CORNER_STEPS``
    steps between two rows, the curve turns steep inside that gap (a braid contact),
    and the plateau's centre joined to the row after the jump would spread the turn
    over half the plateau (a slope of 0.35 kPa/mL where the curve is flat, then 1.8:
    an actuator's fold, where a segment's slope passes its partner's falling one,
    moved to the row after the jump, 0.2 kPa too high). So the plateau's row at the
    jump is kept, at a quarter step from the plateau's value towards the jump (its
    value is within half a step of the plateau's, and the curve nears the next level
    there). Returns (v, p, l, runs merged)."""
    v_c, p_c, l_c, merged = collapse_plateaus(v, p, length)
    if not merged or step_kpa <= 0:
        return v_c, p_c, l_c, merged
    jump = np.diff(p)
    starts = _run_starts(p)
    ends = np.r_[starts[1:], len(v)] - 1  # last row of each run
    extra_v, extra_p, extra_l = [], [], []
    for k, (a, b) in enumerate(zip(starts, ends, strict=True)):
        if b == a:
            continue
        # the jump after the run (into the next) and before it (from the previous)
        if b + 1 < len(v) and abs(jump[b]) >= CORNER_STEPS * step_kpa * (1 - 1e-6):
            extra_v.append(v[b])
            extra_p.append(p[b] + 0.25 * step_kpa * np.sign(jump[b]))
            extra_l.append(length[b])
        if a > 0 and k > 0 and abs(jump[a - 1]) >= CORNER_STEPS * step_kpa * (1 - 1e-6):
            extra_v.append(v[a])
            extra_p.append(p[a] - 0.25 * step_kpa * np.sign(jump[a - 1]))
            extra_l.append(length[a])
    if not extra_v:
        return v_c, p_c, l_c, merged
    v_all = np.r_[v_c, extra_v]
    order = np.argsort(v_all, kind="stable")
    return v_all[order], np.r_[p_c, extra_p][order], np.r_[l_c, extra_l][order], merged


def _fit_noisy(v, p, length, resolution: TableResolution, dip_shown: bool):
    """Bin, decide the shape (a dip only if it stands out of the noise of the bins and
    of the table's step) and fit it: returns (v, p, l, offset) on the bins, or None if
    the fitted curve still falls at its end. ``dip_shown``: the rows are an undithered
    staircase that falls (``stair_edges.shows_dip``), whose dip is the curve's however
    shallow, and whose bins, means of a monotone staircase, fall only there.

    The curve up to the valley and the curve after it are smoothed apart: the valley is
    where the braids touch the tube, a corner, which a smoothing across it would raise
    (by 0.2 kPa for B42-T24 at 0.25 kPa noise, and an actuator's snap moves with it).
    A rising part is the least-squares fit whose slope has one minimum
    (``one_minimum_slope_rise``) where its residuals are noise, else the least-smoothed
    spline of its shape (``smooth_with_shape``), with the bins' own means kept where the
    curve is steep; if no smoothing gives the shape,
    the isotonic fit's block centres. The offset at v = 0 is ``zero_offset`` of the
    first bins' means (the smoothed values there are the least certain)."""
    v_bin, (p_bin, l_bin), counts = binned_trimmed_means(v, [p, length], min(MAX_BINS, len(v)))
    # a dip of a few steps is rounding only where nothing dithers the steps: with noise
    # of at least half a step the bins' means average the quantisation out (B42-T26's
    # 0.6 kPa dip at 0.5 kPa noise on a 0.27 kPa step stands out of its bins' noise by
    # 10 standard errors), and what a dip must stand out of is their noise alone
    min_dip = STEP_PROMINENCE * resolution.step_kpa if resolution.quantised else 0.0
    if dip_shown:
        fit = fit_rise_fall_rise(p_bin, counts, min_dip_kpa=0.0, noise_kpa=0.0)
        min_dip = 0.0
    else:
        fit = fit_rise_fall_rise(p_bin, counts, min_dip_kpa=min_dip)
    if len(fit.branches) == 3:
        valley = min(fit.branches[1][-1][2], fit.branches[2][0][2])
        if fit.branches[2][-1][2] - valley <= max(DIP_NOISE_FACTOR * fit.noise_kpa, min_dip):
            return None
    steep = steep_weight(p_bin, fit.noise_kpa)
    # the noise of each bin's mean: the rows' noise over the square root of the bin's
    # rows; with less noise than quantisation step the rounding errors of neighbouring
    # rows are not independent (a staircase), and they do not average out
    sigma = np.maximum(
        resolution.noise_kpa / np.sqrt(counts),
        resolution.step_kpa
        / np.sqrt(12)
        / np.sqrt(counts if resolution.noise_kpa >= resolution.step_kpa else 1),
    )
    offset = zero_offset(v_bin[:OFFSET_BINS], p_bin[:OFFSET_BINS], sigma[:OFFSET_BINS])
    branch_starts = [branch[0][0] for branch in fit.branches]
    # steep bins weigh more: the spline follows them there and smooths the flat rest
    weights = counts * (1.0 + STEEP_WEIGHT_GAIN * steep)
    smooth = _smooth_parts(v_bin, p_bin, weights, branch_starts, sigma)
    if smooth is not None:
        smooth, constrained = smooth
        # a branch fitted with its curvature constrained follows a steep part as it is
        values = keep_steep_means(p_bin, smooth, np.where(constrained, 0.0, steep))
        # a spline smooth enough for the shape can still miss the data (a flat start
        # before a stiff end: by 20 kPa); then the blocks, which follow it, are the fit
        follows = np.all(np.abs(values - p_bin) <= FOLLOW_SIGMAS * sigma)
        # a tangent clamped flat repeats a value: a plateau the caller collapses, no piece
        distinct = values[np.r_[True, np.diff(values) != 0]]
        if monotone_pieces(distinct) == len(fit.branches) and follows:
            return v_bin, values, l_bin, offset
    blocks = [block for branch in fit.branches for block in branch]
    v_fit = np.array([np.average(v_bin[a:b], weights=counts[a:b]) for a, b, _ in blocks])
    p_fit = np.array([value for _, _, value in blocks])
    return v_fit, p_fit, np.interp(v_fit, v_bin, l_bin), offset


def zero_offset(v, p, sigma) -> float:
    """The sensor's offset: the quadratic through the first bins' means (``sigma``
    their standard errors) at v = 0, or 0 where it does not stand out of its own
    uncertainty (``OFFSET_SIGMAS``). Extrapolated from a few noisy bins it is uncertain
    by 2-3 bins' errors (0.3 kPa at 50 rows/mL and 0.3 kPa noise), and removing it
    would shift the whole curve, peak and valley, by that much: an actuator's snap
    moves by 0.2 mL per 0.1 kPa of a library valley. A real offset (the MPX5100's is
    up to 2.5 kPa) stands out and is removed.

    The uncertainty is also the quadratic's own: a library segment's start is steep and
    bends fast (2-3 kPa per 0.1 mL row), which no quadratic through four rows follows to
    the rows' 0.003 kPa rounding error. Where the bins miss it by more than their errors
    (a reduced chi-square above 1), its covariance is scaled by that chi-square (the
    Birge ratio): on a table rounded to 0.01 kPa every 0.1 mL, whose first row reads
    0.00 at v = 0, the quadratic's -0.04 kPa at v = 0 was removed as an offset and moved
    the whole curve, valley too, by that much (two valleys 0.006 kPa apart swapped: a
    spurious snap)."""
    if len(v) < 3:
        return 0.0
    weights = 1.0 / np.asarray(sigma)
    coefficients, cov = np.polyfit(v, p, 2, w=weights, cov="unscaled")
    offset = float(coefficients[-1])
    dof = len(v) - 3
    if dof > 0:
        chi2 = float(np.sum((weights * (p - np.polyval(coefficients, v))) ** 2)) / dof
        cov = cov * max(chi2, 1.0)
    return offset if abs(offset) > OFFSET_SIGMAS * math.sqrt(cov[-1, -1]) else 0.0


def _smooth_parts(v, p, weights, branch_starts: list[int], sigma):
    """The smooth curve on the bins, branch by branch (``branch_starts``: the first bin
    of each): a rising branch is the fit whose slope has one minimum (concave up to a
    peak, convex after a valley: ``one_minimum_slope_rise``) or, where the data resolve
    more, the smoothest spline the noise allows (``smooth_with_shape``); a falling
    branch the weighted least-squares polynomial of the lowest degree (cubic down to
    linear) that falls all along it, because what an actuator's folds depend on there
    is the slope, which is small (-0.3 to -0.6 kPa/mL for the library) and which a
    spline would let flicker by more than itself. The branches are joined as the
    envelope of their continuations (the lower one at a peak, the upper at a valley: a
    corner such as the braids' contact is kept, with no undershoot or steep drop into
    it). Returns (values on the bins, which bins a one-minimum-slope fit gave), or None
    if a branch cannot be given its shape."""
    edges = [*branch_starts, len(v)]
    fits: list = [None] * len(branch_starts)
    constrained = np.zeros(len(v), dtype=bool)
    for k in range(0, len(branch_starts), 2):
        a, b = edges[k], edges[k + 1]
        values = one_minimum_slope_rise(
            v[a:b], p[a:b], sigma[a:b], concave=len(edges) == 4 and k == 0, convex=k == 2
        )
        if values is not None:
            fits[k] = functools.partial(np.interp, xp=v[a:b], fp=values)
            constrained[a:b] = True
            continue
        # a rising branch whose first (or, before a peak, last) bins are still flat
        # within the noise gives them to the falling branch next to it, a few bins at most
        for shift in range(JOIN_BINS + 1):
            a = edges[k] + (shift if k > 0 else 0)
            b = edges[k + 1] - (shift if k + 1 < len(branch_starts) else 0)
            fit = smooth_with_shape(v[a:b], p[a:b], weights[a:b], 1, sigma=sigma[a:b])
            if fit is not None:
                edges[k], edges[k + 1] = a, b
                fits[k] = fit
                break
        else:
            return None
    for k in range(1, len(branch_starts), 2):
        a, b = edges[k], edges[k + 1]
        fits[k] = falling_polynomial(v[a:b], p[a:b], 1.0 / sigma[a:b] ** 2)
        if fits[k] is None:
            return None
    # each branch continued along its end tangents; a peak is the lower, a valley the
    # upper envelope of the branches that meet there
    c = [
        _continued(fit, v, v[a], v[b - 1], rising=k % 2 == 0)
        for k, (fit, (a, b)) in enumerate(zip(fits, itertools.pairwise(edges), strict=True))
    ]
    if len(c) == 1:
        return c[0], constrained
    peak = np.minimum(c[0], c[1])
    # tangents that meet far from the data (a falling cubic steep at its end) make a
    # spike: then the rise and fall up to the valley are one spline of that shape
    if np.any(np.abs(peak - p)[: edges[2]] > FOLLOW_SIGMAS * sigma[: edges[2]]):
        a, b = 0, edges[2]
        both = smooth_with_shape(v[a:b], p[a:b], weights[a:b], 2, sigma=sigma[a:b])
        if both is None:
            return None
        peak = _continued(both, v, v[a], v[b - 1], rising=True)
        constrained[a:b] = False
    # the last branch, continued back from its valley, only meets the falling one
    return np.where(v >= v[edges[1]], np.maximum(peak, c[2]), peak), constrained


def _continued(fit, x, lo: float, hi: float, *, rising: bool) -> np.ndarray:
    """``fit`` on [lo, hi], continued along its end tangents outside (a cubic's own
    continuation can turn back within a few bins), each tangent no steeper than flat
    against the branch's direction (a spline's end may bend between its bins)."""
    h = 1e-6 * (hi - lo)
    bound = max if rising else min
    slope_lo = bound((fit(lo + h) - fit(lo)) / h, 0.0)
    slope_hi = bound((fit(hi) - fit(hi - h)) / h, 0.0)
    inside = fit(np.clip(x, lo, hi))
    return np.where(
        x < lo,
        fit(lo) + slope_lo * (x - lo),
        np.where(x > hi, fit(hi) + slope_hi * (x - hi), inside),
    )


def falling_polynomial(x, y, w):
    """The weighted least-squares polynomial of the lowest degree from 3 down to 1 that
    decreases all along x (a callable), or None."""
    if len(x) < 2:
        return None
    fine = np.linspace(x[0], x[-1], 200)
    for degree in range(min(3, len(x) - 1), 0, -1):
        poly = np.polynomial.Polynomial.fit(x, y, degree, w=np.sqrt(w))
        if np.all(np.diff(poly(fine)) < 0):
            return poly
    return None


def steep_weight(means, noise_kpa: float) -> np.ndarray:
    """Per bin, 1 where the curve is steep (it changes by more than twice
    ``STEEP_NOISE_FACTOR`` noise levels per bin: the noise is nothing there, and
    smoothing would only round the steep start and the stiffening end), 0 where it is
    flat, blended over a few bins."""
    means = np.asarray(means, dtype=float)
    if len(means) < 5 or noise_kpa <= 0:
        return np.zeros(len(means))
    change = np.abs(np.gradient(means))
    weight = np.clip(change / (STEEP_NOISE_FACTOR * noise_kpa) - 1.0, 0.0, 1.0)
    return np.convolve(np.pad(weight, 2, mode="edge"), np.ones(5) / 5, "valid")


def keep_steep_means(means, smooth, weight) -> np.ndarray:
    """The bins' own means where the curve is steep (``steep_weight``), the smooth
    curve where it is not; the smooth curve alone if the blend loses its shape."""
    blended = weight * np.asarray(means, dtype=float) + (1.0 - weight) * smooth
    return blended if monotone_pieces(blended) == monotone_pieces(smooth) else smooth


def _extend(v, p, length):
    """Continue a curve that ends below P_END_KPA along a line with its final slope
    (the secant over the last fifth of the final rising branch, at least 1 kPa/mL)."""
    if p[-1] >= P_END_KPA - 1.0:  # analytical tables end at P_END_KPA up to rounding
        return v, p, length, None
    last_branch_start = _branch_bounds(v, p)[-1][0]
    span = v[-1] - v[last_branch_start]
    k = min(int(np.searchsorted(v, v[-1] - 0.2 * span)), len(v) - 2)
    slope = max((p[-1] - p[k]) / (v[-1] - v[k]), MIN_END_SLOPE_KPA_PER_ML)
    step = np.arange(1, EXTENSION_SAMPLES + 1) / EXTENSION_SAMPLES * (P_END_KPA - p[-1]) / slope
    return (
        np.concatenate([v, v[-1] + step]),
        np.concatenate([p, p[-1] + slope * step]),
        np.concatenate([length, np.full(EXTENSION_SAMPLES, length[-1])]),
        slope,
    )


def load_csv(
    path: Path | str, *, V0_ml: float | None = None, name: str | None = None
) -> SegmentCurve:
    """A clean ``SegmentCurve`` from a measured-curve CSV (see the module docstring)."""
    path = Path(path)
    return curve_from_table(
        read_csv_table(path), name=name or path.stem, where=str(path), V0_ml=V0_ml
    )


def curve_from_table(
    table: np.ndarray, *, name: str, where: str, V0_ml: float | None = None
) -> SegmentCurve:
    """The one route from a valid table (rows of volume_ml, pressure_kpa, length_mm,
    volume increasing; rows at a repeated volume are averaged) to a ``SegmentCurve``:
    used as tabulated when it is clean at its own resolution (only plateaus of equal
    values, which are collapsed, no dip smaller than ``TableResolution.prominence_kpa``
    and slopes the rounding does not hide), else fitted. ``where``
    names the data's origin in errors and in the curve's source."""
    raw = np.array(table, dtype=float)
    v, p, length, repeated = average_repeated_volumes(*raw.T)
    if len(v) < MIN_ROWS:
        raise InputError(
            f"{where}: {len(v)} distinct volumes; a curve needs at least {MIN_ROWS} "
            "(write volume_ml with more decimals)"
        )
    resolution = resolution_of(v, p)
    notes = [resolution.describe()]
    if repeated:
        notes.append(f"{repeated} rows at a repeated volume averaged")
    v_c, p_c, l_c, merged = keep_corner_rows(v, p, length, resolution.step_kpa)
    # an undithered coarse staircase that falls shows its dip, however shallow
    staircase = resolution.step_kpa >= EDGE_MIN_STEP_KPA and not repeated
    dip_shown = staircase and shows_dip(v, p)
    min_dip = 0.0 if dip_shown else resolution.prominence_kpa
    if dip_shown:
        notes.append("an undithered staircase: the dip it shows counts, however shallow")
    # rows at a repeated volume mark a raw acquisition log, not a curve: always fitted
    if (
        not repeated
        and len(v_c) >= 4
        and _has_segment_shape(v_c, p_c, min_dip, bounds := _branch_bounds(v_c, p_c))
        and slopes_resolved(v_c, p_c, resolution, bounds)
    ):
        route = ROUTE_TABULATED
        v, p, length = v_c, p_c, l_c
        notes.append("used as tabulated")
        if merged:
            plural = "s" if merged > 1 else ""
            notes.append(f"{merged} plateau{plural} of equal pressure collapsed to their centres")
    else:
        route = ROUTE_FITTED
        fitted = _fit_noisy(v, p, length, resolution, dip_shown)
        if fitted is None or not _has_segment_shape(fitted[0], fitted[1]):
            raise InputError(
                f"{where}: the pressure still falls at the last rows (v = {v[-1]:g} mL): "
                "measure past the valley, until the curve stiffens again"
            )
        # where a branch's tangent was flat, the envelope can repeat a value: one row
        v, p, length, _ = collapse_plateaus(*fitted[:3])
        offset = fitted[3]
        notes.append(f"fitted rise-fall-rise to {len(v)} samples")
    if staircase:
        refined = refine_extrema(*raw[:, :2].T, v, p)
        if refined is not None and _has_segment_shape(*refined):
            length = np.interp(refined[0], v, length)
            v, p = refined
            notes.append("peak and valley estimated from the stair edges")
    if route == ROUTE_TABULATED:  # zero at v = 0: extrapolate the first two samples
        offset = p[0] - (p[1] - p[0]) / (v[1] - v[0]) * v[0]
    p = p - offset
    if v[0] > 0:
        # the zero row starts the curve; fitted samples at or below it (the first bins'
        # noise against the offset's quadratic) would make the curve fall first, a fold
        # at v = 0. The first branch rises: those samples are a prefix
        first = int(np.argmax(p > 0))
        v, p, length = v[first:], p[first:], length[first:]
        v, p, length = np.r_[0.0, v], np.r_[0.0, p], np.r_[length[0], length]
    if offset != 0:
        notes.append(f"offset {offset:+.3f} kPa removed")
    v, p, length, slope = _extend(v, p, length)
    if slope is not None:
        notes.append(f"extended linearly at {slope:.2f} kPa/mL to {P_END_KPA:g} kPa")
    curve = SegmentCurve(
        name,
        v,
        p,
        length,
        V0_ml=np.pi * TUBE_RADIUS_MM**2 * length[0] / 1000 if V0_ml is None else V0_ml,
        source=f"measured curve {where} ({'; '.join(notes)})",
    )
    peak, valley = curve.peak, curve.valley
    dip = 0.0 if peak is None or valley is None else peak.p_kpa - valley.p_kpa
    measured = MeasuredImport(resolution, route, peak is not None, dip, min_dip, tuple(notes), raw)
    return dataclasses.replace(curve, measured=measured)


def write_csv(curve: SegmentCurve, path: Path | str) -> None:
    """Write a curve in the measured-curve format, at full precision (shortest repr
    that reads back to the same float)."""
    lines = [",".join(HEADER)]
    lines += [
        f"{float(v)!r},{float(p)!r},{float(length)!r}"
        for v, p, length in zip(curve.v_ml, curve.p_kpa, curve.l_mm, strict=True)
    ]
    Path(path).write_text("\n".join(lines) + "\n", encoding="utf-8")
