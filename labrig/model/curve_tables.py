"""Segment curves as packed arrays, and the compiled functions that evaluate them.

The quasi-static path evaluates a few numbers at a time, hundreds of thousands of times
per scan chunk: the volume of every segment on its branch at a pressure, a segment's
pressure and slope at a volume. numpy's per-call overhead would dominate such work and
CPython spends ~6 us on one branch inversion, so these run compiled (numba): ~0.3 us,
plus ~0.6 us to call from Python.

``pack`` copies the PCHIP pieces of one or more segments into arrays padded to one
length (a ``CurveTables``); ``CurveKernel`` holds the tables of its own segment, a path
solver those of its actuator (``tables_of``), and the post-snap flow
(``labrig.model.ros2_flow``) reads the same arrays. The numbers are those of
``SegmentCurve``: the same cubic pieces, the same linear continuation past both ends.

Compilation takes a few seconds once; the machine code is cached next to this file
(``cache=True``) and reused by every later process.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from functools import lru_cache
from typing import NamedTuple

import numpy as np
from numba import njit

# Newton on a branch's cubic piece stops when the step is below this fraction of the
# sample spacing (the interpolant itself is only defined to rounding, ~1e-16).
T_TOL = 1e-13

# columns of CurveTables.ends
V_FIRST, V_LAST, P_FIRST, P_LAST, SLOPE_FIRST, SLOPE_LAST = range(6)


class CurveTables(NamedTuple):
    """n segments' curves, padded to one length W (a tuple, so compiled code takes it
    as one argument).

    x: (n, W) breakpoints, +inf past a segment's last; c: (n, 4, W-1) coefficients
    c3..c0 of each piece in powers of (v - x_j); samples: (n, W) pressures at the
    breakpoints; ends: (n, 6) v_first, v_last, p_first, p_last, slope_first,
    slope_last (the linear continuations); last_piece: (n,); branch_first,
    branch_last: (n, B) sample indices of each monotone branch; branch_rising: (n, B).
    """

    x: np.ndarray
    c: np.ndarray
    samples: np.ndarray
    ends: np.ndarray
    last_piece: np.ndarray
    branch_first: np.ndarray
    branch_last: np.ndarray
    branch_rising: np.ndarray


def pack(kernels: Sequence) -> CurveTables:
    """The tables of ``kernels`` (objects with a ``CurveKernel``'s list attributes)."""
    n = len(kernels)
    width = max(len(k.x) for k in kernels)
    n_branches = max(len(k.branches) for k in kernels)
    x = np.full((n, width), np.inf)
    c = np.zeros((n, 4, width - 1))
    samples = np.zeros((n, width))
    ends = np.empty((n, 6))
    last_piece = np.empty(n, dtype=np.int64)
    branch_first = np.zeros((n, n_branches), dtype=np.int64)
    branch_last = np.zeros((n, n_branches), dtype=np.int64)
    branch_rising = np.zeros((n, n_branches), dtype=np.bool_)
    for i, k in enumerate(kernels):
        m = len(k.x)
        x[i, :m] = k.x
        c[i, :, : m - 1] = (k.c3, k.c2, k.c1, k.c0)
        samples[i, :m] = k.samples
        ends[i] = (k.v_first, k.v_last, k.p_first, k.p_last, k.slope_first, k.slope_last)
        last_piece[i] = k.last_piece
        for j, b in enumerate(k.branches):
            branch_first[i, j], branch_last[i, j], branch_rising[i, j] = b.first, b.last, b.rising
    return CurveTables(
        x, c, samples, ends, last_piece, branch_first, branch_last, branch_rising
    )  # fmt: skip


@lru_cache(maxsize=256)
def tables_of(kernels: tuple) -> CurveTables:
    """``pack(kernels)``, once per tuple of kernels (an actuator's)."""
    return pack(kernels)


@njit(cache=True)
def piece_index(tables, i, v):
    """The piece of segment i that holds v (bisect_right - 1, clamped to the pieces)."""
    x = tables.x
    lo, hi = 0, tables.last_piece[i] + 2
    while lo < hi:
        mid = (lo + hi) // 2
        if v < x[i, mid]:
            hi = mid
        else:
            lo = mid + 1
    return min(max(lo - 1, 0), tables.last_piece[i])


@njit(cache=True)
def pressure_and_slope(tables, i, v):
    """(p, dp/dv) of segment i at volume v."""
    ends = tables.ends
    if v > ends[i, V_LAST]:
        return ends[i, P_LAST] + ends[i, SLOPE_LAST] * (v - ends[i, V_LAST]), ends[i, SLOPE_LAST]
    if v < ends[i, V_FIRST]:
        return (
            ends[i, P_FIRST] + ends[i, SLOPE_FIRST] * (v - ends[i, V_FIRST]),
            ends[i, SLOPE_FIRST],
        )
    j = piece_index(tables, i, v)
    t = v - tables.x[i, j]
    c = tables.c
    c3, c2, c1 = c[i, 0, j], c[i, 1, j], c[i, 2, j]
    return ((c3 * t + c2) * t + c1) * t + c[i, 3, j], (3.0 * c3 * t + 2.0 * c2) * t + c1


@njit(cache=True)
def volume_on_branch(tables, i, branch, p):
    """(v, dp/dv) of segment i on ``branch`` at pressure ``p``; values outside the
    branch's pressure range are clamped to its ends (the caller keeps p inside), except
    past the table's last sample, where the linear continuation is inverted."""
    first = tables.branch_first[i, branch]
    last = tables.branch_last[i, branch]
    rising = tables.branch_rising[i, branch]
    samples = tables.samples
    ends = tables.ends
    last_sample = tables.last_piece[i] + 1
    if last == last_sample and ((p > ends[i, P_LAST]) if rising else (p < ends[i, P_LAST])):
        return ends[i, V_LAST] + (p - ends[i, P_LAST]) / ends[i, SLOPE_LAST], ends[i, SLOPE_LAST]
    # position = bisect_right(branch samples in ascending order, p) - 1
    lo, hi = 0, last - first + 1
    while lo < hi:
        mid = (lo + hi) // 2
        value = samples[i, first + mid] if rising else samples[i, last - mid]
        if p < value:
            hi = mid
        else:
            lo = mid + 1
    position = min(max(lo - 1, 0), last - first - 1)
    j = first + position if rising else last - 1 - position
    c = tables.c
    c3, c2, c1, c0 = c[i, 0, j], c[i, 1, j], c[i, 2, j], c[i, 3, j]
    h = tables.x[i, j + 1] - tables.x[i, j]
    rhs = p - c0
    p0, p1 = samples[i, j], samples[i, j + 1]
    t = (p - p0) / (p1 - p0) * h if p1 != p0 else 0.5 * h
    t = min(max(t, 0.0), h)
    lo_t, hi_t = 0.0, h
    sign = 1.0 if rising else -1.0
    for _ in range(100):
        f = ((c3 * t + c2) * t + c1) * t - rhs
        if f == 0.0:
            break
        if sign * f > 0:
            hi_t = t
        else:
            lo_t = t
        d = (3.0 * c3 * t + 2.0 * c2) * t + c1
        step = t - f / d if d != 0.0 else -1.0
        if not lo_t < step < hi_t:
            step = 0.5 * (lo_t + hi_t)
        if abs(step - t) <= T_TOL * h:
            t = step
            break
        t = step
    d = (3.0 * c3 * t + 2.0 * c2) * t + c1
    # at a branch's extremum the slope is 0 up to rounding; never let rounding give it
    # the sign of the neighbouring branch
    return tables.x[i, j] + t, max(d, 0.0) if rising else min(d, 0.0)


@njit(cache=True)
def volumes_on_branches(tables, branches, p):
    """``volume_on_branch`` of every segment (segment i on ``branches[i]``) at one
    pressure: (v, dp/dv) arrays."""
    n = len(branches)
    v, k = np.empty(n), np.empty(n)
    for i in range(n):
        v[i], k[i] = volume_on_branch(tables, i, branches[i], p)
    return v, k


@njit(cache=True)
def compensated_sum(values):
    """Neumaier's compensated sum (``math.fsum`` to within an ulp for a few terms)."""
    total = 0.0
    compensation = 0.0
    for a in values:
        t = total + a
        if abs(total) >= abs(a):
            compensation += (total - t) + a
        else:
            compensation += (a - t) + total
        total = t
    return total + compensation


@njit(cache=True)
def excess_volume(p, args):
    """sum_i v_i(p) - v on a branch combination; args = (tables, branches, v)."""
    tables, branches, v = args
    return compensated_sum(volumes_on_branches(tables, branches, p)[0]) - v


@njit(cache=True)
def inverse_slope_sum(p, args):
    """dv/dp = sum_i 1/k_i(p) on a branch combination, a branch end (k = 0) counting as
    +-inf by its side; args = (tables, branches)."""
    tables, branches = args
    total = 0.0
    for i in range(len(branches)):
        k = volume_on_branch(tables, i, branches[i], p)[1]
        if k == 0.0:
            total += math.inf if tables.branch_rising[i, branches[i]] else -math.inf
        else:
            total += 1.0 / k
    return total


@njit(cache=True)
def pair_imbalance(w1, args):
    """p_1(w1) - p_2(v - w1) of two segments holding v together; args = (tables, v)."""
    tables, v = args
    return pressure_and_slope(tables, 0, w1)[0] - pressure_and_slope(tables, 1, v - w1)[0]
