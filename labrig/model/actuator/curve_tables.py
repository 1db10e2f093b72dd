"""Segment curves as packed arrays, and the compiled functions that evaluate them.

The quasi-static path evaluates a few numbers at a time, hundreds of thousands of times
per scan chunk: the volume of every segment on its branch at a pressure, a segment's
pressure and slope at a volume. numpy's per-call overhead would dominate such work and
CPython spends ~6 us on one branch inversion, so these run compiled (numba): ~0.3 us,
plus ~0.6 us to call from Python.

``pack`` copies the PCHIP pieces of one or more segments into arrays padded to one
length (a pair of arrays, floats and integers); ``CurveKernel`` holds the tables of its
own segment, a path solver those of its actuator (``tables_of``), and the post-snap flow
(``labrig.model.actuator.rosenbrock_flow``) reads the same arrays. The numbers are those of
``SegmentCurve``: the same cubic pieces, the same linear continuation past both ends.

Compilation takes a few seconds once; the machine code is cached next to this file
(``cache=True``) and reused by every later process.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from functools import lru_cache

import numpy as np

from labrig.model.actuator.array_loops import count_at_or_below, interp, sorted_unique
from labrig.model.actuator.jit import INTERNAL, INTERNAL_LEAF, LEAF, njit

# Newton on a branch's cubic piece stops when the step is below this fraction of the
# sample spacing (the interpolant itself is only defined to rounding, ~1e-16).
T_TOL = 1e-13

# columns of the ENDS table
V_FIRST, V_LAST, P_FIRST, P_LAST, SLOPE_FIRST, SLOPE_LAST = range(6)


# The tables are a pair of arrays (compiled code takes them as one argument), for n
# segments padded to W samples and B branches: the floats (n, FLOAT_ROWS, W) and the
# integers (n, INT_ROWS, B). Two arrays rather than one per field: every compiled call
# passes each array field by field (data, shape, strides and a reference count), and
# numba lowers that passing, in Python, for every call and every variable: the compile
# of the solver is most of a first scan. Rows of the floats, by index:
BREAKPOINTS = 0  # breakpoints x, +inf past a segment's last
SAMPLES = 1  # pressures at the breakpoints
# the exact integral of p over each piece (W-1 columns), and their running sum from the
# first sample: energy differences are sums of small numbers rather than differences of
# large ones (~10^3 mJ)
PIECE_ENERGY = 2
CUMULATIVE_ENERGY = 3
C3, C2, C1, C0 = 4, 5, 6, 7  # each piece's coefficients in powers of (v - x_j) (W-1 columns)
LC3, LC2, LC1, LC0 = 8, 9, 10, 11  # the length's cubic pieces (W-1 columns)
ENDS = 12  # columns V_FIRST..SLOPE_LAST: the linear continuations past the ends
FLOAT_ROWS = 13
# rows of the integers: each monotone branch's first and last sample index and whether
# it rises (1) or falls (0), and the last piece (column 0)
BRANCH_FIRST, BRANCH_LAST, BRANCH_RISING, LAST_PIECE = range(4)
INT_ROWS = 4
FLOATS, INTS = 0, 1


def pack(kernels: Sequence) -> tuple:
    """The tables of ``kernels`` (objects with a ``CurveKernel``'s list attributes);
    ``tables_of`` stacks those of single kernels, which is faster."""
    n = len(kernels)
    width = _capacity(max(len(k.x) for k in kernels))
    n_branches = max(MAX_BRANCHES, *(len(k.branches) for k in kernels))
    floats = np.zeros((n, FLOAT_ROWS, width))
    floats[:, BREAKPOINTS] = np.inf
    ints = np.zeros((n, INT_ROWS, n_branches), dtype=np.int64)
    for i, k in enumerate(kernels):
        m = len(k.x)
        floats[i, BREAKPOINTS, :m] = k.x
        floats[i, SAMPLES, :m] = k.samples
        floats[i, C3 : C0 + 1, : m - 1] = (k.c3, k.c2, k.c1, k.c0)
        floats[i, LC3 : LC0 + 1, : m - 1] = (k.lc3, k.lc2, k.lc1, k.lc0)
        ends = (k.v_first, k.v_last, k.p_first, k.p_last, k.slope_first, k.slope_last)
        floats[i, ENDS, : len(ends)] = ends
        ints[i, LAST_PIECE, 0] = k.last_piece
        for j, b in enumerate(k.branches):
            ints[i, BRANCH_FIRST : BRANCH_RISING + 1, j] = (b.first, b.last, b.rising)
    _energies(floats, ints)
    return floats, ints


# A segment's tables are padded to a multiple of this many samples, and to this many
# branches (rise, fall, rise), so that the tables of most actuators stack without
# padding: np.concatenate per table, 4x faster than padding row by row.
_CAPACITY_STEP = 64
MAX_BRANCHES = 3
# what pads each table past a segment's own length (x: +inf keeps bisection inside)
_PADDING = {FLOATS: (BREAKPOINTS, np.inf)}


def _capacity(size: int) -> int:
    return -(-size // _CAPACITY_STEP) * _CAPACITY_STEP


def _stacked(parts: list[tuple], padding: dict[int, tuple[int, float]]) -> tuple:
    """One table per field from the one-row tables of ``parts``: concatenated where
    their shapes agree, else padded to the largest with 0, or with ``value`` in the row
    of a field where ``padding[field]`` is (row, value)."""
    out = []
    for field, rows in enumerate(zip(*parts, strict=True)):
        if all(r.shape == rows[0].shape for r in rows):
            out.append(np.concatenate(rows))
            continue
        shape = tuple(max(sizes) for sizes in zip(*(r.shape for r in rows), strict=True))
        table = np.zeros((len(rows), *shape[1:]), dtype=rows[0].dtype)
        if field in padding:
            row, value = padding[field]
            table[:, row] = value
        for i, row in enumerate(rows):
            table[(i, *(slice(0, size) for size in row.shape[1:]))] = row[0]
        out.append(table)
    return tuple(out)


@lru_cache(maxsize=256)
def tables_of(kernels: tuple) -> tuple:
    """The tables of an actuator's kernels (once per tuple of kernels): their own
    one-segment tables (``CurveKernel.tables``) stacked."""
    return _stacked([k.tables for k in kernels], _PADDING)


# The slope profiles (``CurveKernel.slope_profile``) of every branch of n segments, a
# plain tuple too: pressures and values (n, B, P) padded, and their counts (n, B).
PROFILE_P, PROFILE_G, PROFILE_COUNT = range(3)


def pack_profiles(kernel) -> tuple:
    """The slope profiles of every branch of one kernel, as one-row tables."""
    profiles = [kernel.slope_profile(b) for b in range(kernel.n_branches)]
    width = _capacity(max(len(ps) for ps, _ in profiles))
    p = np.zeros((1, max(MAX_BRANCHES, len(profiles)), width))
    g = np.zeros_like(p)
    count = np.zeros((1, p.shape[1]), dtype=np.int64)
    for b, (ps, gs) in enumerate(profiles):
        p[0, b, : len(ps)], g[0, b, : len(gs)], count[0, b] = ps, gs, len(ps)
    return p, g, count


@lru_cache(maxsize=256)
def profiles_of(kernels: tuple) -> tuple:
    """The slope profiles of every branch of ``kernels``, stacked (once per tuple)."""
    return _stacked([k.profile_tables for k in kernels], {})


@njit(**LEAF)
def piece_index(tables, i, v):
    """The piece of segment i that holds v (bisect_right - 1, clamped to the pieces)."""
    f = tables[FLOATS]
    last_piece = tables[INTS][i, LAST_PIECE, 0]
    lo, hi = 0, last_piece + 2
    while lo < hi:
        mid = (lo + hi) // 2
        if v < f[i, BREAKPOINTS, mid]:
            hi = mid
        else:
            lo = mid + 1
    return min(max(lo - 1, 0), last_piece)


@njit(**LEAF)
def spacing_near(tables, i, v):
    """Width of segment i's table interval around v: the scale of a tolerance in v."""
    j = piece_index(tables, i, v)
    return tables[FLOATS][i, BREAKPOINTS, j + 1] - tables[FLOATS][i, BREAKPOINTS, j]


@njit(**LEAF)
def piece_integral(f, i, j, t):
    """Integral of segment i's pressure over its piece j from its start to t in (``f``
    the floats of the tables)."""
    return (
        ((f[i, C3, j] * 0.25 * t + f[i, C2, j] / 3.0) * t + f[i, C1, j] * 0.5) * t + f[i, C0, j]
    ) * t


@njit(cache=True)
def _energies(f, ints):
    """Fills the PIECE_ENERGY and CUMULATIVE_ENERGY rows of the floats ``f`` (zero past
    each segment's last piece)."""
    n, _, width = f.shape
    for i in range(n):
        f[i, CUMULATIVE_ENERGY, 0] = 0.0
        for j in range(width - 1):  # 0 past the last piece
            f[i, PIECE_ENERGY, j] = 0.0
            f[i, CUMULATIVE_ENERGY, j + 1] = 0.0
        for j in range(ints[i, LAST_PIECE, 0] + 1):
            h = f[i, BREAKPOINTS, j + 1] - f[i, BREAKPOINTS, j]
            f[i, PIECE_ENERGY, j] = piece_integral(f, i, j, h)
            f[i, CUMULATIVE_ENERGY, j + 1] = f[i, CUMULATIVE_ENERGY, j] + f[i, PIECE_ENERGY, j]


@njit(**LEAF)
def energy(tables, i, v):
    """E(v) = integral of p from the first sample (Eq. 1), mJ."""
    f = tables[FLOATS]
    if v > f[i, ENDS, V_LAST]:
        d = v - f[i, ENDS, V_LAST]
        return (
            f[i, CUMULATIVE_ENERGY, tables[INTS][i, LAST_PIECE, 0] + 1]
            + f[i, ENDS, P_LAST] * d
            + 0.5 * f[i, ENDS, SLOPE_LAST] * d * d
        )
    if v < f[i, ENDS, V_FIRST]:
        d = v - f[i, ENDS, V_FIRST]
        return f[i, ENDS, P_FIRST] * d + 0.5 * f[i, ENDS, SLOPE_FIRST] * d * d
    j = piece_index(tables, i, v)
    return f[i, CUMULATIVE_ENERGY, j] + piece_integral(f, i, j, v - f[i, BREAKPOINTS, j])


@njit(**LEAF)
def energy_between(tables, i, v_from, v_to):
    """E(v_to) - E(v_from) of segment i, mJ, summed from small terms: the pieces'
    integrals between the two volumes, never the difference of two cumulative energies
    (~10^3 mJ), which would hide the differences below 1e-9 mJ that decide a minimum
    near a peak."""
    sign = 1.0
    if v_to < v_from:
        v_from, v_to, sign = v_to, v_from, -1.0
    f = tables[FLOATS]
    v_first, v_last = f[i, ENDS, V_FIRST], f[i, ENDS, V_LAST]
    total = 0.0
    compensation = 0.0
    if v_from < v_first:  # the linear continuation below the table
        a = v_from - v_first
        b = min(v_to, v_first) - v_first
        term = f[i, ENDS, P_FIRST] * (b - a) + 0.5 * f[i, ENDS, SLOPE_FIRST] * (b * b - a * a)
        total, compensation = _neumaier_add(total, compensation, term)
    if v_to > v_last:  # the linear continuation past the table
        a = max(v_from, v_last) - v_last
        b = v_to - v_last
        term = f[i, ENDS, P_LAST] * (b - a) + 0.5 * f[i, ENDS, SLOPE_LAST] * (b * b - a * a)
        total, compensation = _neumaier_add(total, compensation, term)
    lo = max(v_from, v_first)
    hi = min(v_to, v_last)
    if hi > lo:
        ja, jb = piece_index(tables, i, lo), piece_index(tables, i, hi)
        head = piece_integral(f, i, ja, lo - f[i, BREAKPOINTS, ja])
        if ja == jb:
            term = piece_integral(f, i, ja, hi - f[i, BREAKPOINTS, ja]) - head
            total, compensation = _neumaier_add(total, compensation, term)
        else:
            term = f[i, PIECE_ENERGY, ja] - head
            total, compensation = _neumaier_add(total, compensation, term)
            for j in range(ja + 1, jb):
                total, compensation = _neumaier_add(total, compensation, f[i, PIECE_ENERGY, j])
            term = piece_integral(f, i, jb, hi - f[i, BREAKPOINTS, jb])
            total, compensation = _neumaier_add(total, compensation, term)
    return sign * (total + compensation)


@njit(**LEAF)
def reduced_energy_change(x, tables, previous, v):
    """Eq. 4's reduced energy at x = (v_1..v_{n-1}), v_n = v - sum(x) (Eq. 2), as a
    difference from the state ``previous`` (all n volumes), summed from small terms."""
    n = len(previous)
    last = v - compensated_sum(x)
    total = 0.0
    compensation = 0.0
    for i in range(n - 1):
        term = energy_between(tables, i, previous[i], x[i])
        total, compensation = _neumaier_add(total, compensation, term)
    term = energy_between(tables, n - 1, previous[n - 1], last)
    total, compensation = _neumaier_add(total, compensation, term)
    return total + compensation


@njit(**LEAF)
def length(tables, i, v):
    """l(v) in mm; constant past the table's ends."""
    f = tables[FLOATS]
    v = min(max(v, f[i, ENDS, V_FIRST]), f[i, ENDS, V_LAST])
    j = piece_index(tables, i, v)
    t = v - f[i, BREAKPOINTS, j]
    return ((f[i, LC3, j] * t + f[i, LC2, j]) * t + f[i, LC1, j]) * t + f[i, LC0, j]


@njit(**LEAF)
def total_energy(tables, v):
    """Energy stored in all segments at volumes v (Eq. 3), mJ."""
    total = 0.0
    for i in range(len(v)):
        total += energy(tables, i, v[i])
    return total


@njit(**LEAF)
def total_length(tables, v):
    """Sum of the segments' lengths at volumes v, mm."""
    total = 0.0
    for i in range(len(v)):
        total += length(tables, i, v[i])
    return total


@njit(**LEAF)
def pressure_and_slope(tables, i, v):
    """(p, dp/dv) of segment i at volume v."""
    f = tables[FLOATS]
    if v > f[i, ENDS, V_LAST]:
        slope = f[i, ENDS, SLOPE_LAST]
        return f[i, ENDS, P_LAST] + slope * (v - f[i, ENDS, V_LAST]), slope
    if v < f[i, ENDS, V_FIRST]:
        slope = f[i, ENDS, SLOPE_FIRST]
        return f[i, ENDS, P_FIRST] + slope * (v - f[i, ENDS, V_FIRST]), slope
    j = piece_index(tables, i, v)
    t = v - f[i, BREAKPOINTS, j]
    c3, c2, c1 = f[i, C3, j], f[i, C2, j], f[i, C1, j]
    return ((c3 * t + c2) * t + c1) * t + f[i, C0, j], (3.0 * c3 * t + 2.0 * c2) * t + c1


@njit(**LEAF)
def volume_on_branch(tables, i, branch, p):
    """(v, dp/dv) of segment i on ``branch`` at pressure ``p``; values outside the
    branch's pressure range are clamped to its ends (the caller keeps p inside), except
    past the table's last sample, where the linear continuation is inverted."""
    f, ints = tables
    first = ints[i, BRANCH_FIRST, branch]
    last = ints[i, BRANCH_LAST, branch]
    rising = ints[i, BRANCH_RISING, branch]
    last_sample = ints[i, LAST_PIECE, 0] + 1
    p_last = f[i, ENDS, P_LAST]
    if last == last_sample and ((p > p_last) if rising else (p < p_last)):
        slope = f[i, ENDS, SLOPE_LAST]
        return f[i, ENDS, V_LAST] + (p - p_last) / slope, slope
    # position = bisect_right(branch samples in ascending order, p) - 1
    lo, hi = 0, last - first + 1
    while lo < hi:
        mid = (lo + hi) // 2
        value = f[i, SAMPLES, first + mid] if rising else f[i, SAMPLES, last - mid]
        if p < value:
            hi = mid
        else:
            lo = mid + 1
    position = min(max(lo - 1, 0), last - first - 1)
    j = first + position if rising else last - 1 - position
    c3, c2, c1, c0 = f[i, C3, j], f[i, C2, j], f[i, C1, j], f[i, C0, j]
    h = f[i, BREAKPOINTS, j + 1] - f[i, BREAKPOINTS, j]
    rhs = p - c0
    p0, p1 = f[i, SAMPLES, j], f[i, SAMPLES, j + 1]
    t = (p - p0) / (p1 - p0) * h if p1 != p0 else 0.5 * h
    t = min(max(t, 0.0), h)
    lo_t, hi_t = 0.0, h
    sign = 1.0 if rising else -1.0
    for _ in range(100):
        f_t = ((c3 * t + c2) * t + c1) * t - rhs
        if f_t == 0.0:
            break
        if sign * f_t > 0:
            hi_t = t
        else:
            lo_t = t
        d = (3.0 * c3 * t + 2.0 * c2) * t + c1
        step = t - f_t / d if d != 0.0 else -1.0
        if not lo_t < step < hi_t:
            step = 0.5 * (lo_t + hi_t)
        if abs(step - t) <= T_TOL * h:
            t = step
            break
        t = step
    d = (3.0 * c3 * t + 2.0 * c2) * t + c1
    # at a branch's extremum the slope is 0 up to rounding; never let rounding give it
    # the sign of the neighbouring branch
    return f[i, BREAKPOINTS, j] + t, max(d, 0.0) if rising else min(d, 0.0)


@njit(cache=True)
def volumes_on_branches(tables, branches, p):
    """``volume_on_branch`` of every segment (segment i on ``branches[i]``) at one
    pressure: (v, dp/dv) arrays."""
    n = len(branches)
    v, k = np.empty(n), np.empty(n)
    for i in range(n):
        v[i], k[i] = volume_on_branch(tables, i, branches[i], p)
    return v, k


@njit(**INTERNAL_LEAF)
def _neumaier_add(total, compensation, a):
    """One term of Neumaier's compensated sum: (total, compensation) after adding a."""
    t = total + a
    if abs(total) >= abs(a):
        compensation += (total - t) + a
    else:
        compensation += (a - t) + total
    return t, compensation


@njit(**INTERNAL_LEAF)
def compensated_sum(values):
    """Neumaier's compensated sum (``math.fsum`` to within an ulp for a few terms)."""
    total = 0.0
    compensation = 0.0
    for a in values:
        total, compensation = _neumaier_add(total, compensation, a)
    return total + compensation


# The objectives below are evaluated thousands of times per actuator inside root
# searches. Each takes its arrays as separate arguments and sums term by term as it
# inverts: packing the tables into a tuple per call (an atomic reference count per
# array) and allocating the volumes took more time than the inversions themselves.
# The terms and their order are those of ``compensated_sum`` and ``inverse_sum_of``.
@njit(**INTERNAL_LEAF)
def excess_volume_at(p, tables, branches, v):
    """sum_i v_i(p) - v on a branch combination."""
    total = 0.0
    compensation = 0.0
    for i in range(len(branches)):
        a = volume_on_branch(tables, i, branches[i], p)[0]
        total, compensation = _neumaier_add(total, compensation, a)
    return (total + compensation) - v


@njit(**LEAF)
def excess_volume(p, args):
    """``excess_volume_at`` with args = (tables, branches, v)."""
    tables, branches, v = args
    return excess_volume_at(p, tables, branches, v)


@njit(**INTERNAL_LEAF)
def _inverse_term(tables, i, branch, k):
    """1/k of segment i, +-inf at a branch end (k = 0) by the branch's side."""
    if k == 0.0:
        return math.inf if tables[INTS][i, BRANCH_RISING, branch] else -math.inf
    return 1.0 / k


@njit(**LEAF)
def inverse_sum_of(tables, branches, k):
    """dv/dp = sum_i 1/k_i of a state on ``branches`` with slopes k; a branch end
    (k = 0) counts as +-inf by its side."""
    total = 0.0
    for i in range(len(branches)):
        total += _inverse_term(tables, i, branches[i], k[i])
    return total


@njit(**INTERNAL_LEAF)
def inverse_slope_sum_at(p, tables, branches):
    """``inverse_sum_of`` the state at pressure p on a branch combination."""
    total = 0.0
    for i in range(len(branches)):
        k = volume_on_branch(tables, i, branches[i], p)[1]
        total += _inverse_term(tables, i, branches[i], k)
    return total


@njit(**LEAF)
def pair_imbalance(w1, tables, v):
    """p_1(w1) - p_2(v - w1) of two segments holding v together."""
    return pressure_and_slope(tables, 0, w1)[0] - pressure_and_slope(tables, 1, v - w1)[0]


@njit(**LEAF)
def singular_distance(tables, i, branch, p):
    """Pressure distance from p to the nearer end of segment i's ``branch`` that is an
    extremum of the curve (where the slope is 0); 1.0 kPa if neither is."""
    f, ints = tables
    first = ints[i, BRANCH_FIRST, branch]
    last = ints[i, BRANCH_LAST, branch]
    distance = math.inf
    if first > 0:
        distance = abs(p - f[i, SAMPLES, first])
    if last < ints[i, LAST_PIECE, 0] + 1:
        distance = min(distance, abs(p - f[i, SAMPLES, last]))
    return 1.0 if distance == math.inf else distance


# fractions of a sample interval at which slope profiles close in on an extremum
_TOWARD_END = np.array([0.5, 0.25, 0.1, 0.03, 0.01, 0.003, 0.001])


def slope_profile(tables, i, branch) -> tuple[np.ndarray, np.ndarray]:
    """Segment i's slope profile on ``branch`` (``CurveKernel.slope_profile``): its
    points sorted by p, then by value."""
    ints = tables[INTS]
    room = 2 * int(ints[i, BRANCH_LAST, branch] - ints[i, BRANCH_FIRST, branch])
    room += 2 * len(_TOWARD_END) + 1
    p, r = np.empty(room), np.empty(room)
    count = slope_profile_points(tables, i, branch, _TOWARD_END, p, r)
    p, r = p[:count], r[:count]
    order = np.lexsort((r, p))
    return p[order], r[order]


@njit(**LEAF)
def slope_profile_points(tables, i, branch, toward_end, p_out, r_out):
    """The points of segment i's slope profile on ``branch``, unsorted, into ``p_out``
    and ``r_out``; returns how many. The outputs need room for 2 per sample interval,
    2 * len(toward_end) + 1 more (``slope_profile``). Compiled: a profile evaluates p,
    dp/dv and the extremum distance at every sample and more (~200 points a branch),
    and these calls from Python were most of the time spent building the solver's
    tables for a new curve."""
    f, ints = tables
    first = ints[i, BRANCH_FIRST, branch]
    last = ints[i, BRANCH_LAST, branch]
    rising = ints[i, BRANCH_RISING, branch]
    count = 0
    for j in range(first, last):
        x_j, x_next = f[i, BREAKPOINTS, j], f[i, BREAKPOINTS, j + 1]
        h = x_next - x_j
        count = _profile_point(tables, i, branch, rising, x_j, p_out, r_out, count)
        c3, c2 = f[i, C3, j], f[i, C2, j]
        if c3 != 0.0:
            t = -c2 / (3.0 * c3)
            if 0.0 < t < h:  # the slope's extremum inside the interval
                count = _profile_point(tables, i, branch, rising, x_j + t, p_out, r_out, count)
        if j == first and first > 0:  # leaving an extremum sample
            for fraction in toward_end:
                count = _profile_point(
                    tables, i, branch, rising, x_j + h * fraction, p_out, r_out, count
                )
        if j == last - 1 and last < ints[i, LAST_PIECE, 0] + 1:  # arriving at one
            for fraction in toward_end:
                count = _profile_point(
                    tables, i, branch, rising, x_next - h * fraction, p_out, r_out, count
                )
    return _profile_point(tables, i, branch, rising, f[i, BREAKPOINTS, last], p_out, r_out, count)


@njit(**INTERNAL_LEAF)
def _profile_point(tables, i, branch, rising, v, p_out, r_out, count):
    """One profile point at v, if the slope there has the branch's sign."""
    p, k = pressure_and_slope(tables, i, v)
    if (k > 0.0) == rising and k != 0.0:
        p_out[count] = p
        r_out[count] = math.sqrt(singular_distance(tables, i, branch, p)) / k
        count += 1
    return count


@njit(**INTERNAL)
def fold_screen(tables, profiles, branches, p_from, p_to, margin):
    """Pressures strictly between p_from and p_to, in the order the path meets them,
    where the screened sum of 1/k comes within ``margin`` of its terms' magnitudes
    from 0 (``labrig.model.actuator.path``, ``_find_fold``): each segment's slope profile,
    interpolated linearly in p and divided by sqrt of the distance to the branch's
    extremum, summed over the segments, at every profile pressure of every segment."""
    lo, hi = min(p_from, p_to), max(p_from, p_to)
    n = len(branches)
    total_points = 0
    for i in range(n):
        total_points += profiles[PROFILE_COUNT][i, branches[i]]
    candidates = np.empty(total_points)
    m = 0
    for i in range(n):
        ps = profiles[PROFILE_P][i, branches[i], : profiles[PROFILE_COUNT][i, branches[i]]]
        j = count_at_or_below(ps, lo)  # the profile's pressures above lo and below hi
        while j < len(ps) and ps[j] < hi:
            candidates[m] = ps[j]
            m += 1
            j += 1
    pressures = sorted_unique(candidates[:m])
    total, scale = np.empty(len(pressures)), np.empty(len(pressures))
    for j in range(len(pressures)):
        total[j] = scale[j] = 0.0
    for i in range(n):
        b = branches[i]
        ps = profiles[PROFILE_P][i, b, : profiles[PROFILE_COUNT][i, b]]
        gs = profiles[PROFILE_G][i, b, : profiles[PROFILE_COUNT][i, b]]
        values = interp(pressures, ps, gs)
        for j in range(len(pressures)):
            distance = singular_distance(tables, i, b, pressures[j])
            if distance > 0.0:
                value = values[j] / math.sqrt(distance)
                total[j] += value
                scale[j] += abs(value)
    flagged = np.empty(len(pressures))
    m = 0
    for j in range(len(pressures)):
        if total[j] >= -margin * scale[j]:
            flagged[m] = pressures[j]
            m += 1
    return flagged[:m][::-1] if p_to < p_from else flagged[:m]


# The functions whose roots the solver seeks (``labrig.model.actuator.roots``), by number: a
# compiled function passed as an argument would cost ~7 us per call to type and could
# not be cached.
EXCESS_VOLUME, INVERSE_SLOPE_SUM, PAIR_IMBALANCE = range(3)


@njit(**INTERNAL_LEAF)
def objective(kind, x, tables, branches, v):
    """``excess_volume_at`` (x a pressure), ``inverse_slope_sum_at`` (x a pressure; v unused)
    or ``pair_imbalance`` (x the first segment's volume; branches unused)."""
    if kind == EXCESS_VOLUME:
        return excess_volume_at(x, tables, branches, v)
    if kind == INVERSE_SLOPE_SUM:
        return inverse_slope_sum_at(x, tables, branches)
    return pair_imbalance(x, tables, v)
