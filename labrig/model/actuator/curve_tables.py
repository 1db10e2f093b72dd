"""Segment curves as packed arrays, and the compiled functions that evaluate them.

The quasi-static path evaluates a few numbers at a time, hundreds of thousands of times
per scan chunk: the volume of every segment on its branch at a pressure, a segment's
pressure and slope at a volume. numpy's per-call overhead would dominate such work and
CPython spends ~6 us on one branch inversion, so these run compiled (numba): ~0.3 us,
plus ~0.6 us to call from Python.

``pack`` copies the PCHIP pieces of one or more segments into arrays padded to one
length (a tuple of arrays, ``pack``); ``CurveKernel`` holds the tables of its own segment, a path
solver those of its actuator (``tables_of``), and the post-snap flow
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


# The tables are a plain tuple of arrays, for n segments padded to one length W
# (compiled code takes it as one argument; a plain tuple crosses from Python to
# compiled code in half the time of a NamedTuple, and these calls are the solver's
# hottest). Its fields, by index:
BREAKPOINTS = 0  # (n, W) breakpoints x, +inf past a segment's last
COEFFS = 1  # (n, 4, W-1) coefficients c3..c0 of each piece in powers of (v - x_j)
SAMPLES = 2  # (n, W) pressures at the breakpoints
ENDS = 3  # (n, 6) columns V_FIRST..SLOPE_LAST: the linear continuations past the ends
LAST_PIECE = 4  # (n,)
BRANCH_FIRST = 5  # (n, B) first sample index of each monotone branch
BRANCH_LAST = 6  # (n, B) last sample index of each monotone branch
BRANCH_RISING = 7  # (n, B)
# (n, W-1) the exact integral of p over each piece, and (n, W) their running sum from
# the first sample: energy differences are sums of small numbers rather than
# differences of large ones (~10^3 mJ)
PIECE_ENERGY = 8
CUMULATIVE_ENERGY = 9
LENGTH_COEFFS = 10  # (n, 4, W-1) the length's cubic pieces


def pack(kernels: Sequence) -> tuple:
    """The tables of ``kernels`` (objects with a ``CurveKernel``'s list attributes);
    ``tables_of`` stacks those of single kernels, which is faster."""
    n = len(kernels)
    width = _capacity(max(len(k.x) for k in kernels))
    n_branches = max(MAX_BRANCHES, *(len(k.branches) for k in kernels))
    x = np.full((n, width), np.inf)
    c = np.zeros((n, 4, width - 1))
    samples = np.zeros((n, width))
    ends = np.empty((n, 6))
    last_piece = np.empty(n, dtype=np.int64)
    branch_first = np.zeros((n, n_branches), dtype=np.int64)
    branch_last = np.zeros((n, n_branches), dtype=np.int64)
    branch_rising = np.zeros((n, n_branches), dtype=np.bool_)
    lc = np.zeros((n, 4, width - 1))
    for i, k in enumerate(kernels):
        m = len(k.x)
        x[i, :m] = k.x
        c[i, :, : m - 1] = (k.c3, k.c2, k.c1, k.c0)
        samples[i, :m] = k.samples
        ends[i] = (k.v_first, k.v_last, k.p_first, k.p_last, k.slope_first, k.slope_last)
        last_piece[i] = k.last_piece
        lc[i, :, : m - 1] = (k.lc3, k.lc2, k.lc1, k.lc0)
        for j, b in enumerate(k.branches):
            branch_first[i, j], branch_last[i, j], branch_rising[i, j] = b.first, b.last, b.rising
    piece_energy, cumulative_energy = _energies(x, c, last_piece)
    return (
        x, c, samples, ends, last_piece, branch_first, branch_last, branch_rising,
        piece_energy, cumulative_energy, lc,
    )  # fmt: skip


# A segment's tables are padded to a multiple of this many samples, and to this many
# branches (rise, fall, rise), so that the tables of most actuators stack without
# padding: np.concatenate per table, 4x faster than padding row by row.
_CAPACITY_STEP = 64
MAX_BRANCHES = 3
# what pads each table past a segment's own length (x: +inf keeps bisection inside)
_PADDING = {BREAKPOINTS: np.inf}


def _capacity(size: int) -> int:
    return -(-size // _CAPACITY_STEP) * _CAPACITY_STEP


def _stacked(parts: list[tuple], padding: dict[int, float]) -> tuple:
    """One table per field from the one-row tables of ``parts``: concatenated where
    their shapes agree, else padded to the largest with ``padding[field]`` (or 0)."""
    out = []
    for field, rows in enumerate(zip(*parts, strict=True)):
        if all(r.shape == rows[0].shape for r in rows):
            out.append(np.concatenate(rows))
            continue
        shape = tuple(max(sizes) for sizes in zip(*(r.shape for r in rows), strict=True))
        table = np.full((len(rows), *shape[1:]), padding.get(field, 0), dtype=rows[0].dtype)
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
    x = tables[BREAKPOINTS]
    lo, hi = 0, tables[LAST_PIECE][i] + 2
    while lo < hi:
        mid = (lo + hi) // 2
        if v < x[i, mid]:
            hi = mid
        else:
            lo = mid + 1
    return min(max(lo - 1, 0), tables[LAST_PIECE][i])


@njit(**LEAF)
def piece_integral(c, i, j, t):
    """Integral of segment i's pressure over its piece j from its start to t in."""
    return (
        ((c[i, 0, j] * 0.25 * t + c[i, 1, j] / 3.0) * t + c[i, 2, j] * 0.5) * t + c[i, 3, j]
    ) * t


@njit(cache=True)
def _energies(x, c, last_piece):
    """The PIECE_ENERGY and CUMULATIVE_ENERGY tables."""
    n, width = x.shape
    pieces = np.empty((n, width - 1))
    cumulative = np.empty((n, width))
    for i in range(n):
        cumulative[i, 0] = 0.0
        for j in range(width - 1):  # 0 past the last piece
            pieces[i, j] = 0.0
            cumulative[i, j + 1] = 0.0
        for j in range(last_piece[i] + 1):
            pieces[i, j] = piece_integral(c, i, j, x[i, j + 1] - x[i, j])
            cumulative[i, j + 1] = cumulative[i, j] + pieces[i, j]
    return pieces, cumulative


@njit(**LEAF)
def energy(tables, i, v):
    """E(v) = integral of p from the first sample (Eq. 1), mJ."""
    ends = tables[ENDS]
    if v > ends[i, V_LAST]:
        d = v - ends[i, V_LAST]
        return (
            tables[CUMULATIVE_ENERGY][i, tables[LAST_PIECE][i] + 1]
            + ends[i, P_LAST] * d
            + 0.5 * ends[i, SLOPE_LAST] * d * d
        )
    if v < ends[i, V_FIRST]:
        d = v - ends[i, V_FIRST]
        return ends[i, P_FIRST] * d + 0.5 * ends[i, SLOPE_FIRST] * d * d
    j = piece_index(tables, i, v)
    return tables[CUMULATIVE_ENERGY][i, j] + piece_integral(
        tables[COEFFS], i, j, v - tables[BREAKPOINTS][i, j]
    )


@njit(**LEAF)
def energy_between(tables, i, v_from, v_to):
    """E(v_to) - E(v_from) of segment i, mJ, summed from small terms: the pieces'
    integrals between the two volumes, never the difference of two cumulative energies
    (~10^3 mJ), which would hide the differences below 1e-9 mJ that decide a minimum
    near a peak."""
    sign = 1.0
    if v_to < v_from:
        v_from, v_to, sign = v_to, v_from, -1.0
    ends = tables[ENDS]
    total = 0.0
    compensation = 0.0
    if v_from < ends[i, V_FIRST]:  # the linear continuation below the table
        a = v_from - ends[i, V_FIRST]
        b = min(v_to, ends[i, V_FIRST]) - ends[i, V_FIRST]
        term = ends[i, P_FIRST] * (b - a) + 0.5 * ends[i, SLOPE_FIRST] * (b * b - a * a)
        total, compensation = _neumaier_add(total, compensation, term)
    if v_to > ends[i, V_LAST]:  # the linear continuation past the table
        a = max(v_from, ends[i, V_LAST]) - ends[i, V_LAST]
        b = v_to - ends[i, V_LAST]
        term = ends[i, P_LAST] * (b - a) + 0.5 * ends[i, SLOPE_LAST] * (b * b - a * a)
        total, compensation = _neumaier_add(total, compensation, term)
    lo = max(v_from, ends[i, V_FIRST])
    hi = min(v_to, ends[i, V_LAST])
    if hi > lo:
        x, c = tables[BREAKPOINTS], tables[COEFFS]
        ja, jb = piece_index(tables, i, lo), piece_index(tables, i, hi)
        head = piece_integral(c, i, ja, lo - x[i, ja])
        if ja == jb:
            term = piece_integral(c, i, ja, hi - x[i, ja]) - head
            total, compensation = _neumaier_add(total, compensation, term)
        else:
            pieces = tables[PIECE_ENERGY]
            total, compensation = _neumaier_add(total, compensation, pieces[i, ja] - head)
            for j in range(ja + 1, jb):
                total, compensation = _neumaier_add(total, compensation, pieces[i, j])
            term = piece_integral(c, i, jb, hi - x[i, jb])
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
    v = min(max(v, tables[ENDS][i, V_FIRST]), tables[ENDS][i, V_LAST])
    j = piece_index(tables, i, v)
    t = v - tables[BREAKPOINTS][i, j]
    lc = tables[LENGTH_COEFFS]
    return ((lc[i, 0, j] * t + lc[i, 1, j]) * t + lc[i, 2, j]) * t + lc[i, 3, j]


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
    ends = tables[ENDS]
    if v > ends[i, V_LAST]:
        return ends[i, P_LAST] + ends[i, SLOPE_LAST] * (v - ends[i, V_LAST]), ends[i, SLOPE_LAST]
    if v < ends[i, V_FIRST]:
        return (
            ends[i, P_FIRST] + ends[i, SLOPE_FIRST] * (v - ends[i, V_FIRST]),
            ends[i, SLOPE_FIRST],
        )
    j = piece_index(tables, i, v)
    t = v - tables[BREAKPOINTS][i, j]
    c = tables[COEFFS]
    c3, c2, c1 = c[i, 0, j], c[i, 1, j], c[i, 2, j]
    return ((c3 * t + c2) * t + c1) * t + c[i, 3, j], (3.0 * c3 * t + 2.0 * c2) * t + c1


@njit(**LEAF)
def volume_on_branch(tables, i, branch, p):
    """(v, dp/dv) of segment i on ``branch`` at pressure ``p``; values outside the
    branch's pressure range are clamped to its ends (the caller keeps p inside), except
    past the table's last sample, where the linear continuation is inverted."""
    first = tables[BRANCH_FIRST][i, branch]
    last = tables[BRANCH_LAST][i, branch]
    rising = tables[BRANCH_RISING][i, branch]
    samples = tables[SAMPLES]
    ends = tables[ENDS]
    last_sample = tables[LAST_PIECE][i] + 1
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
    c = tables[COEFFS]
    c3, c2, c1, c0 = c[i, 0, j], c[i, 1, j], c[i, 2, j], c[i, 3, j]
    h = tables[BREAKPOINTS][i, j + 1] - tables[BREAKPOINTS][i, j]
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
    return tables[BREAKPOINTS][i, j] + t, max(d, 0.0) if rising else min(d, 0.0)


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
        return math.inf if tables[BRANCH_RISING][i, branch] else -math.inf
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
    first = tables[BRANCH_FIRST][i, branch]
    last = tables[BRANCH_LAST][i, branch]
    distance = math.inf
    if first > 0:
        distance = abs(p - tables[SAMPLES][i, first])
    if last < tables[LAST_PIECE][i] + 1:
        distance = min(distance, abs(p - tables[SAMPLES][i, last]))
    return 1.0 if distance == math.inf else distance


# fractions of a sample interval at which slope profiles close in on an extremum
_TOWARD_END = np.array([0.5, 0.25, 0.1, 0.03, 0.01, 0.003, 0.001])


def slope_profile(tables, i, branch) -> tuple[np.ndarray, np.ndarray]:
    """Segment i's slope profile on ``branch`` (``CurveKernel.slope_profile``): its
    points sorted by p, then by value."""
    room = 2 * int(tables[BRANCH_LAST][i, branch] - tables[BRANCH_FIRST][i, branch])
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
    first = tables[BRANCH_FIRST][i, branch]
    last = tables[BRANCH_LAST][i, branch]
    rising = tables[BRANCH_RISING][i, branch]
    x = tables[BREAKPOINTS]
    c = tables[COEFFS]
    count = 0
    for j in range(first, last):
        h = x[i, j + 1] - x[i, j]
        count = _profile_point(tables, i, branch, rising, x[i, j], p_out, r_out, count)
        c3, c2 = c[i, 0, j], c[i, 1, j]
        if c3 != 0.0:
            t = -c2 / (3.0 * c3)
            if 0.0 < t < h:  # the slope's extremum inside the interval
                count = _profile_point(tables, i, branch, rising, x[i, j] + t, p_out, r_out, count)
        if j == first and first > 0:  # leaving an extremum sample
            for f in toward_end:
                count = _profile_point(
                    tables, i, branch, rising, x[i, j] + h * f, p_out, r_out, count
                )
        if j == last - 1 and last < tables[LAST_PIECE][i] + 1:  # arriving at one
            for f in toward_end:
                count = _profile_point(
                    tables, i, branch, rising, x[i, j + 1] - h * f, p_out, r_out, count
                )
    return _profile_point(tables, i, branch, rising, x[i, last], p_out, r_out, count)


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
