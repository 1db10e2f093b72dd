"""The quasi-static path and its transitions for one actuator, entirely in compiled code.

This module mirrors ``labrig.model.actuator.path`` step for step. That is the
algorithm's readable Python form: a ``_Tracer`` that calls compiled kernels (branch
inversion, the fold search, the post-snap flow) from Python. In a scan that Python glue
between the calls is half the time: building ``State``s, stacking the actuator's tables,
thousands of small calls that each cost microseconds to enter. This module is the same
algorithm, step for step and rounding for rounding, as one numba function per actuator
(``trace_transitions``): a scan enters compiled code once per actuator and gets the
transitions' fields back as arrays.

The same arithmetic in the same order, so the results are the same bits
(tests/model/actuator/test_compiled_path.py holds them equal on chunks and on generated
actuators): ``math.fsum`` is ported exactly (``fsum``), Python's ``min``/``max`` keep
their first argument on a tie (``_min``, ``_max``), ``itertools.product`` and
``combinations`` keep their order. What the reference does only on rare, hard states
is not ported: a flow stalled on a saddle (pushed off along an eigenvector), a state
lost in ``state_on_piece``'s fallback. There, and on any error, this module gives up
(``Unported`` or the error itself) and the scan runs that actuator through the
reference, whose result or error is then the actuator's (``labrig.model.scan.scan``).

A state here is a tuple (branches, p, v, k): int64 and float64 arrays of the segments'
branches, volumes and slopes, and the common pressure.
"""

from __future__ import annotations

import math

import numpy as np

from labrig.model.actuator.array_loops import (
    arange,
    copy_into,
    differs,
    largest,
    sorted_unique,
    stable_order,
)
from labrig.model.actuator.curve_tables import (
    BRANCH_LAST,
    BRANCH_RISING,
    BREAKPOINTS,
    ENDS,
    EXCESS_VOLUME,
    FLOAT_ROWS,
    FLOATS,
    INT_ROWS,
    INTS,
    LAST_PIECE,
    PAIR_IMBALANCE,
    SAMPLES,
    V_FIRST,
    V_LAST,
    excess_volume_at,
    inverse_sum_of,
    pair_imbalance,
    pressure_and_slope,
    profiles_of,
    spacing_near,
    tables_of,
    total_energy,
    total_length,
    volume_on_branch,
    volumes_on_branches,
)
from labrig.model.actuator.equilibria import stable_slopes
from labrig.model.actuator.fold_search import AT_PRESSURE, AT_VOLUME, START, at_volume_of, find_fold
from labrig.model.actuator.jit import INLINE, INTERNAL, INTERNAL_LEAF, njit
from labrig.model.actuator.roots import XTOL, bracketed_root
from labrig.model.actuator.rosenbrock_flow import MAX_STEPS, SETTLED, settle_flow

# the rows ``library_tables`` adds to the tables: per segment, the pressure and volume
# range of each branch (floats), and the number of branches and the peak's branch (-1
# without a peak; integers, column 0)
P_LO, P_HI, V_LO, V_HI = range(FLOAT_ROWS, FLOAT_ROWS + 4)
N_BRANCHES, PEAK_BRANCH = INT_ROWS, INT_ROWS + 1
# timeline items and the events' kinds (``labrig.model.actuator.path.Event``)
PIECE, EVENT = 0, 1
SNAP, CROSSING = 0, 1
CAUSE_FOLD, CAUSE_COINCIDENT, CAUSE_BRANCH_END, CAUSE_COINCIDENT_ENDS = range(4)
INFLATE, DEFLATE = 1, -1
# timeline items one direction may hold here (the reference allows 10,000 events)
_CAPACITY = 256
_HEAD = 4  # the timeline's columns before an item's branches and states
_MAX_FLOW_STEPS = 200_000  # ``descent.settle``'s default


class Unported(RuntimeError):
    """A state the compiled path leaves to the reference (see the module docstring)."""


def library_tables(kernels: tuple) -> tuple:
    """(tables, profiles) of every kernel of a library, stacked: what
    ``trace_transitions`` selects an actuator's rows from. The tables carry the branch
    facts besides (P_LO..PEAK_BRANCH), so that the compiled path passes one pair of
    arrays for all it reads of the curves."""
    floats, ints = tables_of(kernels)
    n, _, width = floats.shape
    branches = ints.shape[2]
    facts = np.zeros((n, 4, width))
    counts = np.zeros((n, 2, branches), dtype=np.int64)
    for i, kern in enumerate(kernels):
        for j, b in enumerate(kern.branches):
            facts[i, :, j] = (b.p_lo_kpa, b.p_hi_kpa, b.v_lo_ml, b.v_hi_ml)
        counts[i, :, 0] = kern.n_branches, -1 if kern.peak_branch is None else kern.peak_branch
    tables = (np.concatenate((floats, facts), axis=1), np.concatenate((ints, counts), axis=1))
    return tables, profiles_of(kernels)


# --- Python's arithmetic, exactly ------------------------------------------------------
@njit(**INTERNAL_LEAF)
def _max(a, b):
    """Python's ``max(a, b)``: the first unless the second is larger."""
    return b if b > a else a


@njit(**INTERNAL_LEAF)
def _min(a, b):
    """Python's ``min(a, b)``: the first unless the second is smaller."""
    return b if b < a else a


@njit(cache=True)
def fsum(values):
    """``math.fsum``: CPython's algorithm (Shewchuk's partials, correctly rounded)."""
    partials = np.empty(len(values) + 1)
    n = 0
    special = 0.0
    inf_sum = 0.0
    for value in values:
        x = value
        i = 0
        for j in range(n):
            y = partials[j]
            if abs(x) < abs(y):
                x, y = y, x
            hi = x + y
            yr = hi - x
            lo = y - yr
            if lo != 0.0:
                partials[i] = lo
                i += 1
            x = hi
        n = i
        if x != 0.0:
            if not math.isfinite(x):
                if math.isfinite(value):
                    raise OverflowError("intermediate overflow in fsum")
                if math.isinf(value):
                    inf_sum += value
                special += value
                n = 0
            else:
                partials[n] = x
                n += 1
    if special != 0.0:
        if math.isnan(inf_sum):
            raise ValueError("-inf + inf in fsum")
        return special
    hi = 0.0
    if n > 0:
        n -= 1
        hi = partials[n]
        lo = 0.0
        while n > 0:
            x = hi
            n -= 1
            y = partials[n]
            hi = x + y
            yr = hi - x
            lo = y - yr
            if lo != 0.0:
                break
        if n > 0 and ((lo < 0.0 and partials[n - 1] < 0.0) or (lo > 0.0 and partials[n - 1] > 0.0)):
            y = lo * 2.0
            x = hi + y
            yr = x - hi
            if y == yr:
                hi = x
    return hi


# --- states --------------------------------------------------------------------------
@njit(**INTERNAL)
def _at(tables, b, p):
    v, k = volumes_on_branches(tables, b, p)
    return b.copy(), p, v, k


@njit(**INTERNAL_LEAF)
def _rising(tables, i, branch):
    return tables[INTS][i, BRANCH_RISING, branch]


@njit(**INTERNAL_LEAF)
def _branch_of(tables, i, v):
    """``CurveKernel.branch_of``."""
    for index in range(tables[INTS][i, N_BRANCHES, 0] - 1):
        if v <= tables[FLOATS][i, V_HI, index]:
            return index
    return tables[INTS][i, N_BRANCHES, 0] - 1


@njit(**INTERNAL)
def _with_volume(tables, state, v):
    """``_Tracer._with_volume``: (found, state)."""
    b, p, vs, ks = state
    residual = v - fsum(vs)
    if abs(residual) <= 1e-9 * _max(1.0, abs(v)):
        return True, state
    found = False
    best_change, best_i, best_v, best_k = 0.0, -1, 0.0, 0.0
    for i in range(len(b)):
        v_i = vs[i] + residual
        if not tables[FLOATS][i, V_LO, b[i]] <= v_i <= tables[FLOATS][i, V_HI, b[i]]:
            continue
        p_i, k_i = pressure_and_slope(tables, i, v_i)
        change = abs(p_i - p)
        if not found or change < best_change:
            k_i = _max(k_i, 0.0) if _rising(tables, i, b[i]) else _min(k_i, 0.0)
            found = True
            best_change, best_i, best_v, best_k = change, i, v_i, k_i
    if not found or best_change > 1e-9 * _max(1.0, abs(p)):
        return False, state
    volumes, slopes = vs.copy(), ks.copy()
    volumes[best_i], slopes[best_i] = best_v, best_k
    return True, (b, p, volumes, slopes)


@njit(**INTERNAL)
def _reach_between(tables, b, p_a, p_b, v_target, f_a, f_b):
    p = bracketed_root(EXCESS_VOLUME, tables, b, v_target, p_a, p_b, f_a, f_b, XTOL)
    found, reached = _with_volume(tables, _at(tables, b, p), v_target)
    if not found:
        raise RuntimeError("no equilibrium at the target volume")
    return reached


@njit(**INLINE)
def _reach(tables, state, v_target, has_end, end, s_p):
    b, p, vs, _ = state
    v_state = fsum(vs)
    if v_state == v_target:
        return state
    f_start = v_state - v_target
    if not has_end:
        step = _max(1.0, abs(p))
        p_far = p + s_p * step
        while (excess_volume_at(p_far, tables, b, v_target) > 0) == (f_start > 0):
            step *= 2.0
            p_far = p + s_p * step
        return _reach_between(tables, b, p, p_far, v_target, f_start, math.nan)
    f_end = fsum(end[2]) - v_target
    return _reach_between(tables, b, p, end[1], v_target, f_start, f_end)


# --- folds -------------------------------------------------------------------------
@njit(**INLINE)
def _find_fold(tables, profiles, state, m, p_stop, direction, margin):
    """``_Tracer._find_fold``: (found, state)."""
    b = state[0]
    s_start = inverse_sum_of(tables, b, state[3])
    if math.isnan(s_start):
        step = 1e-7 * _max(1.0, abs(state[1]))
        if math.isfinite(p_stop):
            step = _min(step, 0.5 * abs(p_stop - state[1]))
        state = _at(tables, b, state[1] - direction * step)
        s_start = inverse_sum_of(tables, b, state[3])
    if not math.isfinite(p_stop):
        f = tables[FLOATS]
        v_last = f[m, ENDS, V_LAST]
        p_stop = pressure_and_slope(tables, m, v_last + (v_last - f[m, ENDS, V_FIRST]))[0]
    kind, p, v_m = find_fold(
        tables, profiles, b, m, direction, margin, state[1], state[2], s_start, p_stop
    )
    if kind == AT_PRESSURE:
        return True, _at(tables, b, p)
    if kind == AT_VOLUME:
        p2, v, k = at_volume_of(tables, b, m, v_m)
        return True, (b.copy(), p2, v, k)
    return kind == START, state


@njit(**INTERNAL)
def _fold_residual(k):
    soft = 0
    for x in k:
        if x < 0:
            soft += 1
        if x == 0.0:
            return math.inf
    if soft != 1:
        return math.inf
    inverse, size = np.empty(len(k)), np.empty(len(k))
    for i in range(len(k)):
        inverse[i] = 1.0 / k[i]
        size[i] = abs(inverse[i])
    return abs(fsum(inverse)) / fsum(size)


# --- the flow and where it ends ----------------------------------------------------------
@njit(**INTERNAL)
def _settle(tables, w0, tol, unit):
    """``descent.settle``, but a stall on a saddle is left to the reference."""
    if len(w0) == 2:
        w = w0.copy()
        for _ in range(10):
            w = _settle_pair(tables, w)
            k = np.empty(2)
            for i in range(2):
                k[i] = pressure_and_slope(tables, i, w[i])[1]
            if stable_slopes(k):
                return w
            raise Unported("a pair's flow stalled on a saddle")
        return w
    status, w = settle_flow(tables, w0.copy(), tol * unit, unit, _MAX_FLOW_STEPS)
    if status == SETTLED:
        return w
    if status == MAX_STEPS:
        raise RuntimeError("the flow did not settle")
    raise Unported("the flow stalled on a saddle")


@njit(**INLINE)
def _settle_pair(tables, w):
    """``descent._settle_pair``."""
    v = w[0] + w[1]
    g0 = pair_imbalance(w[0], tables, v)
    if g0 == 0.0:
        return w
    direction = -1.0 if g0 > 0 else 1.0
    end = 0.0 if direction < 0 else v
    f, ints = tables
    m0, m1 = ints[0, LAST_PIECE, 0] + 2, ints[1, LAST_PIECE, 0] + 2
    lo, hi = _min(w[0], end), _max(w[0], end)
    candidates = np.empty(m0 + m1 + 1)  # either curve's knots strictly inside, and the end
    m = 0
    for j in range(m0 + m1):
        knot = f[0, BREAKPOINTS, j] if j < m0 else v - f[1, BREAKPOINTS, j - m0]
        if lo < knot < hi:
            candidates[m] = knot
            m += 1
    candidates[m] = end
    points = sorted_unique(candidates[: m + 1])
    if direction < 0:
        points = points[::-1]
    j = -1
    for index in range(len(points)):
        if direction * pair_imbalance(points[index], tables, v) >= 0:
            j = index
            break
    if j < 0:
        far = end + direction * _max(v, 1.0)
        if direction * pair_imbalance(far, tables, v) < 0:
            raise RuntimeError("the flow between two segments never stops")
        a, b = end, far
    else:
        a = w[0] if j == 0 else points[j - 1]
        b = points[j]
    no_branches = np.empty(0, dtype=np.int64)
    w1 = bracketed_root(PAIR_IMBALANCE, tables, no_branches, v, a, b, math.nan, math.nan, XTOL)
    out = np.empty(2)
    out[0], out[1] = w1, v - w1
    return out


@njit(**INTERNAL)
def _equilibrium_on(tables, b, w, v):
    """``_Tracer._equilibrium_on``: (found, state)."""
    n = len(b)
    p_lo, p_hi = tables[FLOATS][0, P_LO, b[0]], tables[FLOATS][0, P_HI, b[0]]
    for i in range(1, n):
        p_lo = _max(p_lo, tables[FLOATS][i, P_LO, b[i]])
        p_hi = _min(p_hi, tables[FLOATS][i, P_HI, b[i]])
    empty = (b, 0.0, w, w)
    if p_lo > p_hi:
        return False, empty
    pressures = np.empty(n)
    for i in range(n):
        pressures[i] = pressure_and_slope(tables, i, w[i])[0]
    mean_p = fsum(pressures) / n
    p0 = p = _min(_max(mean_p, p_lo), p_hi)
    for _ in range(30):
        state = _at(tables, b, p)
        excess = fsum(state[2]) - v
        if abs(excess) <= 1e-12 * _max(1.0, v):
            return True, state
        slope = inverse_sum_of(tables, b, state[3])
        p = p - excess / slope if math.isfinite(slope) and slope != 0 else math.nan
        if not p_lo <= p <= p_hi:
            break
    f0 = excess_volume_at(p0, tables, b, v)
    width = 1e-6 * _max(1.0, abs(p0))
    while True:
        for side in range(2):
            q = _max(p0 - width, p_lo) if side == 0 else _min(p0 + width, p_hi)
            f = excess_volume_at(q, tables, b, v)
            if (f > 0) != (f0 > 0):
                root = bracketed_root(EXCESS_VOLUME, tables, b, v, p0, q, f0, f, XTOL)
                return _with_volume(tables, _at(tables, b, root), v)
        if p0 - width <= p_lo and p0 + width >= p_hi:
            return False, empty
        width *= 4.0


@njit(**INTERNAL)
def _combinations_near(tables, w, near_ml):
    """``_Tracer._combinations_near``: the combinations as rows, in the same order."""
    n = len(w)
    f = tables[FLOATS]
    options = np.empty((n, 3), dtype=np.int64)
    counts = np.empty(n, dtype=np.int64)
    for i in range(n):
        b = _branch_of(tables, i, w[i])
        options[i, 0] = b
        count = 1
        tol = _max(1e-6 * spacing_near(tables, i, w[i]), near_ml)
        for other in (b - 1, b + 1):
            if (
                0 <= other < tables[INTS][i, N_BRANCHES, 0]
                and f[i, V_LO, other] - tol <= w[i] <= f[i, V_HI, other] + tol
            ):
                options[i, count] = other
                count += 1
        counts[i] = count
    total = 1
    digits = np.empty(n, dtype=np.int64)
    for i in range(n):
        total *= counts[i]
        digits[i] = 0
    product = np.empty((total, n), dtype=np.int64)
    for row in range(total):  # itertools.product: the last position turns fastest
        for i in range(n):
            product[row, i] = options[i, digits[i]]
        i = n - 1
        while i >= 0:
            digits[i] += 1
            if digits[i] < counts[i]:
                break
            digits[i] = 0
            i -= 1
    # sorted (stably) by how many positions differ from the first
    distance = np.empty(total)  # float64: the one type ``stable_order`` is compiled for
    for row in range(total):
        differing = 0.0
        for i in range(n):
            differing += product[row, i] != product[0, i]
        distance[row] = differing
    order = stable_order(distance)
    return product[order]


@njit(**INTERNAL)
def _polish(tables, w, v, near_ml):
    """``_Tracer.polish``."""
    combos = _combinations_near(tables, w, near_ml)
    found_any = False
    first_found = (combos[0].copy(), 0.0, w, w)
    for row in range(len(combos)):
        b = combos[row].copy()
        found, state = _equilibrium_on(tables, b, w, v)
        if found and stable_slopes(state[3]):
            return state
        if found and not found_any:
            found_any, first_found = True, state
    if found_any:
        return first_found
    raise RuntimeError("no equilibrium at the volume")


@njit(**INTERNAL)
def _snap_from_fold(tables, fold, s_p, unit, flow_tol):
    """``_Tracer._snap_from_fold``."""
    b, p, vs, ks = fold
    n = len(ks)
    u = np.empty(n)
    for i in range(n):
        u[i] = s_p / ks[i] if ks[i] != 0 else 0.0
    mean = fsum(u) / n
    for i in range(n):
        u[i] = u[i] - mean
    largest = abs(u[0])
    for i in range(1, n):
        largest = _max(largest, abs(u[i]))
    scale = 1.0 / largest
    for i in range(n):
        u[i] = u[i] * scale
    v_fold = fsum(vs)
    for eta in (0.1 * unit, 1e-2 * unit, 1e-3 * unit, unit):
        w0 = np.empty(n)
        for i in range(n):
            w0[i] = vs[i] + eta * u[i]
        post = _polish(tables, _settle(tables, w0, flow_tol, unit), v_fold, 0.0)
        moved = differs(post[0], b)
        beyond = moved or s_p * (post[1] - p) > 1e-9 * _max(1.0, abs(p))
        if beyond and stable_slopes(post[3]):
            return _past_semi_stable(tables, post, fold, eta, flow_tol, unit)
    raise RuntimeError("no state to snap to from the fold")


@njit(**INLINE)
def _past_semi_stable(tables, post, fold, eta, flow_tol, unit):
    """``_Tracer._past_semi_stable``."""
    zero = _max(10.0 * _fold_residual(fold[3]), 1e-9)
    origin = fold
    n = len(fold[3])
    for _ in range(8):
        if not _fold_residual(post[3]) <= zero:
            return post
        u = np.empty(n)
        for i in range(n):
            u[i] = 1.0 / post[3][i]  # no slope is 0: the residual above is finite
        mean = fsum(u) / n
        along = np.empty(n)  # u against the way the state came
        for i in range(n):
            u[i] = u[i] - mean
            along[i] = u[i] * (post[2][i] - origin[2][i])
        sign = 1.0 if fsum(along) >= 0 else -1.0
        largest = abs(u[0])
        for i in range(1, n):
            largest = _max(largest, abs(u[i]))
        scale = sign / largest
        w0 = np.empty(n)
        for i in range(n):
            w0[i] = post[2][i] + eta * u[i] * scale
        settled = _settle(tables, w0, flow_tol, unit)
        origin, post = post, _polish(tables, settled, fsum(post[2]), 0.0)
    return post


@njit(**INLINE)
def _fold_snap(tables, fold, s_p, unit, flow_tol):
    """The snap from a fold, as ``_cross`` returns its event: (kind, cause, post)."""
    return SNAP, CAUSE_FOLD, _snap_from_fold(tables, fold, s_p, unit, flow_tol)


# --- branch ends -------------------------------------------------------------------
@njit(**INTERNAL_LEAF)
def _switched(tables, i, branch, s_p):
    """``_Tracer._switched``; -1 for None."""
    forward = _rising(tables, i, branch) == (s_p > 0)
    new = branch + (1 if forward else -1)
    return new if 0 <= new < tables[INTS][i, N_BRANCHES, 0] else -1


@njit(**INTERNAL_LEAF)
def _lexicographic_less(a, b):
    """Python's comparison of two tuples of ints, a < b."""
    for i in range(min(len(a), len(b))):
        if a[i] != b[i]:
            return a[i] < b[i]
    return len(a) < len(b)


@njit(**INTERNAL)
def _cross(tables, end, at_limit, s_p, direction, unit, flow_tol):
    """``_Tracer._cross``: (kind, cause, post)."""
    b, p_end, v_end, k_end = end
    n = len(b)
    delta = 1e-7 * _max(1.0, abs(p_end))
    v_end_total = fsum(v_end)
    n_limit = len(at_limit)
    has_best = False
    best_moved = 0.0
    best_subset = np.empty(0, dtype=np.int64)
    best_new = b.copy()
    for size in range(1, n_limit + 1):
        index = arange(size)
        while True:  # itertools.combinations(at_limit, size), in order
            subset = at_limit[index]
            new = b.copy()
            possible = True
            for i in subset:
                switched = _switched(tables, i, b[i], s_p)
                if switched < 0:
                    possible = False
                new[i] = switched
            if possible:
                falling = 0
                for i in range(n):
                    falling += not _rising(tables, i, new[i])
                wanted = direction if falling == 0 else -direction
                if not (falling > 1 or wanted != -s_p):
                    room = math.inf
                    for i in range(n):
                        if s_p < 0:
                            r = tables[FLOATS][i, P_HI, new[i]] - p_end
                        else:
                            r = p_end - tables[FLOATS][i, P_LO, new[i]]
                        room = r if i == 0 else _min(room, r)
                    if room > 0:
                        probe = _at(tables, new, p_end - s_p * _min(delta, 0.5 * room))
                        moved = direction * (fsum(probe[2]) - v_end_total)
                        if stable_slopes(probe[3]) and moved > 0:
                            better = not has_best or moved < best_moved
                            if has_best and moved == best_moved:
                                better = _lexicographic_less(subset, best_subset)
                            if better:
                                has_best = True
                                best_moved, best_subset, best_new = moved, subset, new
            # the next combination of positions
            i = size - 1
            while i >= 0 and index[i] == n_limit - size + i:
                i -= 1
            if i < 0:
                break
            index[i] += 1
            for j in range(i + 1, size):
                index[j] = index[j - 1] + 1
    if has_best:
        cause = CAUSE_BRANCH_END if n_limit == 1 else CAUSE_COINCIDENT_ENDS
        k = k_end.copy()
        for i in at_limit:
            k[i] = 0.0
        return CROSSING, cause, (best_new, p_end, v_end, k)
    none_on = True
    for i in at_limit:
        if _switched(tables, i, b[i], s_p) >= 0:
            none_on = False
    if none_on:
        raise RuntimeError("the path runs past the end of a curve")
    for extra in (1e-2 * unit, 1e-1 * unit):
        w0 = v_end.copy()
        for i in at_limit:
            w0[i] += direction * extra / n_limit
        settled = _settle(tables, w0, flow_tol, unit)
        post = _polish(tables, settled, v_end_total, 2.0 * extra)
        if stable_slopes(post[3]):
            return SNAP, CAUSE_COINCIDENT, post
    raise RuntimeError("the flow from coincident branch ends did not settle")


# --- the timeline ------------------------------------------------------------------
@njit(**INLINE)
def _new_timeline(n):
    """Items, as two arrays (each array a compiled call passes costs code at every
    call): integers (capacity + 1, _HEAD + 2n), an item's type, direction, event kind
    and cause, then branches a and b, and the count of items so far in the last row;
    floats (capacity, _HEAD + 4n), a piece's pressures a, b and volumes a, b (an
    event's are its states' pressures), then an event's volumes and slopes before and
    after."""
    ints = np.empty((_CAPACITY + 1, _HEAD + 2 * n), dtype=np.int64)
    floats = np.empty((_CAPACITY, _HEAD + 4 * n))
    ints[_CAPACITY, 0] = 0
    return ints, floats


@njit(**INTERNAL_LEAF)
def _append_piece(timeline, start, end, direction):
    ints, floats = timeline
    count = ints[_CAPACITY, 0]
    if count >= _CAPACITY:
        raise Unported("too many items on one path")
    ints[count, 0], ints[count, 1] = PIECE, direction
    floats[count, 0], floats[count, 1] = start[1], end[1]
    floats[count, 2], floats[count, 3] = fsum(start[2]), fsum(end[2])
    copy_into(ints[count, _HEAD : _HEAD + len(start[0])], start[0])
    ints[_CAPACITY, 0] = count + 1


@njit(**INTERNAL_LEAF)
def _append_event(timeline, kind, cause, direction, pre, post):
    ints, floats = timeline
    count = ints[_CAPACITY, 0]
    if count >= _CAPACITY:
        raise Unported("too many items on one path")
    ints[count, 0], ints[count, 1], ints[count, 2], ints[count, 3] = EVENT, direction, kind, cause
    floats[count, 0], floats[count, 1] = pre[1], post[1]
    n = len(pre[0])
    copy_into(ints[count, _HEAD : _HEAD + n], pre[0])
    copy_into(ints[count, _HEAD + n : _HEAD + 2 * n], post[0])
    copy_into(floats[count, _HEAD : _HEAD + n], pre[2])
    copy_into(floats[count, _HEAD + n : _HEAD + 2 * n], pre[3])
    copy_into(floats[count, _HEAD + 2 * n : _HEAD + 3 * n], post[2])
    copy_into(floats[count, _HEAD + 3 * n : _HEAD + 4 * n], post[3])
    ints[_CAPACITY, 0] = count + 1


@njit(**INTERNAL)
def _branches_at(timeline, t, side):
    """Item t's branches a (side 0) or b (1), a view (returned with its reference)."""
    ints = timeline[0]
    n = (ints.shape[1] - _HEAD) // 2
    return ints[t, _HEAD + side * n : _HEAD + (side + 1) * n]


@njit(**INTERNAL)
def _event_state(timeline, t, side):
    floats = timeline[1]
    n = (floats.shape[1] - _HEAD) // 4
    v = floats[t, _HEAD + 2 * side * n : _HEAD + (2 * side + 1) * n].copy()
    k = floats[t, _HEAD + (2 * side + 1) * n : _HEAD + (2 * side + 2) * n].copy()
    return _branches_at(timeline, t, side).copy(), floats[t, side], v, k


@njit(**INTERNAL_LEAF)
def _event_cause(timeline, t):
    return timeline[0][t, 3]


@njit(**INTERNAL_LEAF)
def _touched(timeline, first):
    """``path._touched`` on the items from ``first`` on (this direction's)."""
    ints, floats = timeline
    count = ints[_CAPACITY, 0]
    if count - first < 2:
        return False
    if not (ints[count - 2, 0] == EVENT and ints[count - 2, 2] == SNAP):
        return False
    if ints[count - 1, 0] != PIECE:
        return False
    v_from, v_to = floats[count - 1, 2], floats[count - 1, 3]
    size = _max(abs(v_from), abs(v_to))
    return abs(v_to - v_from) <= 1e-10 * size


@njit(**INTERNAL)
def _follow(tables, profiles, timeline, state, direction, v_target, params):
    """``_Tracer.follow``: appends to the timeline; the final state."""
    unit, margin, flow_tol = params
    first = timeline[0][_CAPACITY, 0]
    n = len(state[0])
    limits = np.empty(n)
    while True:
        b = state[0]
        n_falling, m = 0, -1
        for i in range(n):
            if not _rising(tables, i, b[i]):
                if n_falling == 0:
                    m = i
                n_falling += 1
        s_p = direction if n_falling == 0 else -direction
        for i in range(n):
            limits[i] = tables[FLOATS][i, P_HI if s_p > 0 else P_LO, b[i]]
        p_stop = limits[0]
        for i in range(1, n):
            p_stop = _min(p_stop, limits[i]) if s_p > 0 else _max(p_stop, limits[i])
        has_fold, fold = False, state
        if n_falling == 1:
            has_fold, fold = _find_fold(tables, profiles, state, m, p_stop, direction, margin)
        if has_fold and abs(fold[1] - p_stop) <= 1e-10 * _max(1.0, abs(p_stop)):
            has_fold = False
        has_end, end = True, fold
        if not has_fold:
            if math.isfinite(p_stop):
                end = _at(tables, b, p_stop)
            else:
                has_end = False
        if not has_end or direction * (fsum(end[2]) - v_target) >= 0:
            final = _reach(tables, state, v_target, has_end, end, s_p)
            _append_piece(timeline, state, final, direction)
            return final
        _append_piece(timeline, state, end, direction)
        pre = end
        if has_fold:
            kind, cause, post = _fold_snap(tables, fold, s_p, unit, flow_tol)
        else:
            tol = 1e-14 * _max(1.0, abs(p_stop))
            n_limit = 0
            for i in range(n):
                n_limit += abs(limits[i] - p_stop) <= tol
            at_limit = np.empty(n_limit, dtype=np.int64)
            j = 0
            for i in range(n):
                if abs(limits[i] - p_stop) <= tol:
                    at_limit[j] = i
                    j += 1
            kind, cause, post = _cross(tables, end, at_limit, s_p, direction, unit, flow_tol)
        if kind == SNAP and _touched(timeline, first):
            snap = timeline[0][_CAPACITY, 0] - 2
            merged_cause = _event_cause(timeline, snap)
            merged_pre = _event_state(timeline, snap, 0)
            timeline[0][_CAPACITY, 0] = snap
            _append_event(timeline, kind, merged_cause, direction, merged_pre, post)
        else:
            _append_event(timeline, kind, cause, direction, pre, post)
        state = post


# --- the path and its transitions ---------------------------------------------------------
@njit(**INLINE)
def default_end_volume(tables):
    """``path.default_end_volume_ml``."""
    n = len(tables[INTS])
    has_extremum = False
    highest = 0.0
    for i in range(n):
        for j in range(tables[INTS][i, N_BRANCHES, 0] - 1):
            value = tables[FLOATS][i, SAMPLES, tables[INTS][i, BRANCH_LAST, j]]
            highest = value if not has_extremum else _max(highest, value)
            has_extremum = True
    p_end = 0.0
    if has_extremum:
        p_end = 1.1 * highest
    else:
        for i in range(n):
            top = largest(tables[FLOATS][i, SAMPLES, : tables[INTS][i, LAST_PIECE, 0] + 2])
            p_end = top if i == 0 else _max(p_end, top)
    volumes = np.empty(n)
    for i in range(n):
        last = tables[INTS][i, N_BRANCHES, 0] - 1
        p_lo = tables[FLOATS][i, P_LO, last]
        volumes[i] = volume_on_branch(tables, i, last, _max(p_end, p_lo))[0]
    return fsum(volumes)


@njit(**INTERNAL)
def _state_on_piece(tables, timeline, t, v_ml):
    """``path.state_on_piece`` on the timeline's piece t (its fallback left to the
    reference)."""
    floats = timeline[1]
    b = _branches_at(timeline, t, 0).copy()
    p_from, p_to, v_from, v_to = floats[t, 0], floats[t, 1], floats[t, 2], floats[t, 3]
    lo, hi = (v_from, v_to) if v_from <= v_to else (v_to, v_from)
    v = _min(_max(v_ml, lo), hi)
    if v == v_from:
        return _at(tables, b, p_from)
    if v == v_to:
        return _at(tables, b, p_to)
    p = _bracketed_or_nan(tables, b, v, p_from, p_to)
    if math.isnan(p):
        raise Unported("state_on_piece's fallback")
    found, reached = _with_volume(tables, _at(tables, b, p), v)
    if not found:
        raise Unported("state_on_piece's fallback")
    return reached


@njit(**INLINE)
def _bracketed_or_nan(tables, b, v, p_a, p_b):
    """The root ``reach_between`` finds, NaN where it raises (no sign change)."""
    f_a = excess_volume_at(p_a, tables, b, v)
    f_b = excess_volume_at(p_b, tables, b, v)
    if f_a != 0.0 and f_b != 0.0 and (f_a > 0) == (f_b > 0):
        return math.nan
    return bracketed_root(EXCESS_VOLUME, tables, b, v, p_a, p_b, f_a, f_b, XTOL)


@njit(**INLINE)
def _select(library, library_profiles, combo):
    """The rows of ``combo``'s segments: the actuator's tables (their padding to the
    library's widest segment changes no number)."""
    tables = (library[FLOATS][combo], library[INTS][combo])
    q = library_profiles
    profiles = (q[0][combo], q[1][combo], q[2][combo])
    return tables, profiles


@njit(**INTERNAL_LEAF)
def _alpha(tables, branches):
    total = 0
    for i in range(len(branches)):
        peak = tables[INTS][i, PEAK_BRANCH, 0]
        total += peak >= 0 and branches[i] >= peak
    return total


@njit(cache=True)
def trace_transitions(
    library, library_profiles, combo, deflate, unit, margin, flow_tol, window_ml
):  # fmt: skip
    """``transitions(quasi_static_path(actuator, deflate=deflate))`` of the actuator
    made of segments ``combo`` of a library (its ``library_tables``), as arrays: ints
    (m, 4) direction, alpha, beta, stable and floats (m, 5) v_ml, dE, dv, dl, dp."""
    n = len(combo)
    tables, profiles = _select(library, library_profiles, combo)
    params = (unit, margin, flow_tol)
    timeline = _new_timeline(n)
    first_branches = np.empty(n, dtype=np.int64)
    for i in range(n):
        first_branches[i] = 0
    start = _at(tables, first_branches, 0.0)
    v_end = default_end_volume(tables)
    end = _follow(tables, profiles, timeline, start, INFLATE, v_end, params)
    if deflate:
        _follow(tables, profiles, timeline, end, DEFLATE, 0.0, params)
    ints = timeline[0]
    count = ints[_CAPACITY, 0]
    out_ints = np.empty((count, 4), dtype=np.int64)  # the rows returned are all written
    out_floats = np.empty((count, 5))
    rows = 0
    for t in range(count):
        if ints[t, 0] != EVENT:
            continue
        direction = ints[t, 1]
        alpha = _alpha(tables, _branches_at(timeline, t, 0))
        beta = _alpha(tables, _branches_at(timeline, t, 1))
        item_pre = _event_state(timeline, t, 0)
        if ints[t, 2] == SNAP:
            pre, post, stable = item_pre, _event_state(timeline, t, 1), False
        elif alpha != beta:
            v = fsum(item_pre[2])
            half = 0.5 * window_ml * direction
            pre = _state_on_piece(tables, timeline, t - 1, v - half)
            post = _state_on_piece(tables, timeline, t + 1, v + half)
            stable = True
        else:
            continue
        e_pre, e_post = total_energy(tables, pre[2]), total_energy(tables, post[2])
        l_pre, l_post = total_length(tables, pre[2]), total_length(tables, post[2])
        flow = post[2][0] - pre[2][0]
        for i in range(1, n):
            flow = _max(flow, post[2][i] - pre[2][i])
        out_ints[rows, 0], out_ints[rows, 1], out_ints[rows, 2] = direction, alpha, beta
        out_ints[rows, 3] = stable
        out_floats[rows, 0] = fsum(item_pre[2])
        out_floats[rows, 1] = (e_post - e_pre) / e_pre
        out_floats[rows, 2] = flow / fsum(pre[2])
        out_floats[rows, 3] = (l_post - l_pre) / l_pre
        out_floats[rows, 4] = (post[1] - pre[1]) / pre[1]
        rows += 1
    return out_ints[:rows], out_floats[:rows]
