"""The search for the first fold along a piece of the path, compiled with numba.

What is searched and why is explained in ``labrig.model.actuator.path`` (``_find_fold``): the
screened sum of 1/k at every sample pressure of every segment in the piece
(``curve_tables.fold_screen``), exact states at the flagged pressures, brackets refined
down to the falling segment's sample spacing (8 points per level, in order, so the
first fold is found, not a later one), and the fold itself as a root of sum 1/k with a
look at 16 points before it for an earlier sign change. In Python this search was a
quarter of a scan's time: thousands of small states per actuator.

A state here is its pressure, volumes, and how it was made, so that the caller can
rebuild exactly the same ``State``: at a pressure (``AT_PRESSURE``), at a volume of the
falling segment (``AT_VOLUME``, its pressure then follows from that volume), or the
start state passed in (``START``).
"""

from __future__ import annotations

import numpy as np

from labrig.model.actuator.array_loops import copy_into
from labrig.model.actuator.curve_tables import (
    BRANCH_RISING,
    INTS,
    INVERSE_SLOPE_SUM,
    compensated_sum,
    fold_screen,
    inverse_slope_sum_at,
    inverse_sum_of,
    pressure_and_slope,
    spacing_near,
    volumes_on_branches,
)
from labrig.model.actuator.jit import INTERNAL_LEAF, njit
from labrig.model.actuator.roots import bracketed_root

NOT_FOUND, AT_PRESSURE, AT_VOLUME, START = range(4)
# bracket refinement: points per level, and levels at most (a bracket shrinks 8-fold
# per level down to two sample spacings: 12 levels cover 1e10 spacings)
_SPLIT = 8
_MAX_PENDING = _SPLIT * 12 + 2


@njit(cache=True)
def at_volume_of(tables, branches, m, v_m):
    """The state on ``branches`` where segment m holds v_m (its pressure sets the
    others'); (p, v, k). ``labrig.model.actuator.path._Tracer.at_volume_of`` calls this too."""
    p, k_m = pressure_and_slope(tables, m, v_m)
    k_m = max(k_m, 0.0) if tables[INTS][m, BRANCH_RISING, branches[m]] else min(k_m, 0.0)
    v, k = volumes_on_branches(tables, branches, p)
    v[m], k[m] = v_m, k_m
    return p, v, k


@njit(**INTERNAL_LEAF)
def _fold_between(tables, branches, p_a, s_a, p_c, s_c):
    """The first root of sum 1/k between a (negative) and c (not): Brent's root, then a
    look at 16 points before it for an earlier sign change. Returns (found, p): found
    False means 'lost already at a' (a degenerate point)."""
    lo, s_lo, hi, s_hi = p_a, s_a, p_c, s_c
    if not s_lo < 0:
        return False, p_a
    root = p_a
    for _ in range(6):
        root = bracketed_root(INVERSE_SLOPE_SUM, tables, branches, 0.0, lo, hi, s_lo, s_hi, 1e-11)
        earlier = False
        lo_next, s_lo_next = lo, s_lo
        k_found = 0
        q_found, s_q_found = 0.0, 0.0
        for k in range(1, 16):
            q = lo + (root - lo) * k / 16
            s_q = inverse_slope_sum_at(q, tables, branches)
            if s_q >= 0:
                earlier = True
                k_found, q_found, s_q_found = k, q, s_q
                break
            lo_next, s_lo_next = q, s_q
        if not earlier:
            return True, root
        if k_found > 1:
            lo, s_lo = lo_next, s_lo_next
        hi, s_hi = q_found, s_q_found
    return True, root


@njit(cache=True)
def find_fold(
    tables, profiles, branches, m, direction, margin, start_p, start_v, start_s, end_p
):  # fmt: skip
    """The first fold between the start state and the state at ``end_p`` on
    ``branches`` (segment m past its peak, moving in volume ``direction``).

    Returns (kind, p, v_m): NOT_FOUND, a state AT_PRESSURE p, a state AT_VOLUME v_m of
    segment m, or the START state itself (the piece is lost at once)."""
    n = len(branches)
    # pending intervals (prev, cur), each end: kind, p, v_m, s, volumes
    kinds = np.empty((_MAX_PENDING, 2), dtype=np.int64)
    ps = np.empty((_MAX_PENDING, 2))
    vms = np.empty((_MAX_PENDING, 2))
    ss = np.empty((_MAX_PENDING, 2))
    vs = np.empty((_MAX_PENDING, 2, n))
    end_v, end_k = volumes_on_branches(tables, branches, end_p)
    end_s = inverse_sum_of(tables, branches, end_k)
    screened = fold_screen(tables, profiles, branches, start_p, end_p, margin)
    prev_kind, prev_p, prev_vm, prev_s = START, start_p, 0.0, start_s
    prev_v = start_v.copy()
    for index in range(len(screened) + 1):
        if index < len(screened):
            cur_kind, cur_p = AT_PRESSURE, screened[index]
            cur_v, cur_k = volumes_on_branches(tables, branches, cur_p)
            cur_s = inverse_sum_of(tables, branches, cur_k)
        else:
            cur_kind, cur_p, cur_v, cur_s = AT_PRESSURE, end_p, end_v, end_s
        # _check(prev, cur), depth first, sub-intervals in order
        top = 0
        kinds[0, 0], ps[0, 0], vms[0, 0], ss[0, 0] = prev_kind, prev_p, prev_vm, prev_s
        kinds[0, 1], ps[0, 1], vms[0, 1], ss[0, 1] = cur_kind, cur_p, 0.0, cur_s
        copy_into(vs[0, 0], prev_v)
        copy_into(vs[0, 1], cur_v)
        top = 1
        while top > 0:
            top -= 1
            a_v, c_v = vs[top, 0].copy(), vs[top, 1].copy()
            a_kind, a_p, a_vm, a_s = kinds[top, 0], ps[top, 0], vms[top, 0], ss[top, 0]
            c_kind, c_p, c_vm, c_s = kinds[top, 1], ps[top, 1], vms[top, 1], ss[top, 1]
            turned = direction * (compensated_sum(c_v) - compensated_sum(a_v)) < 0
            if not (c_s >= 0 or turned):
                continue
            a_m, c_m = a_v[m], c_v[m]
            if abs(c_m - a_m) > 2.0 * spacing_near(tables, m, a_m):
                # 8 sub-intervals between a, 7 states at volumes of segment m, and c;
                # the first is put on top of the pile, so that they are checked in order
                if top + _SPLIT > _MAX_PENDING:
                    raise RuntimeError("the fold search's brackets nest too deep")
                pt_kind = np.empty(_SPLIT + 1, dtype=np.int64)
                pt_p, pt_vm, pt_s = np.empty(_SPLIT + 1), np.empty(_SPLIT + 1), np.empty(_SPLIT + 1)
                pt_v = np.empty((_SPLIT + 1, n))
                pt_kind[0], pt_p[0], pt_vm[0], pt_s[0] = a_kind, a_p, a_vm, a_s
                copy_into(pt_v[0], a_v)
                pt_kind[_SPLIT], pt_p[_SPLIT], pt_vm[_SPLIT], pt_s[_SPLIT] = c_kind, c_p, c_vm, c_s
                copy_into(pt_v[_SPLIT], c_v)
                for k in range(1, _SPLIT):
                    v_point = a_m + (c_m - a_m) * k / _SPLIT
                    p_point, v, k_point = at_volume_of(tables, branches, m, v_point)
                    pt_kind[k], pt_p[k], pt_vm[k] = AT_VOLUME, p_point, v_point
                    pt_s[k] = inverse_sum_of(tables, branches, k_point)
                    copy_into(pt_v[k], v)
                for i in range(_SPLIT):
                    slot = top + _SPLIT - 1 - i
                    for side in range(2):
                        j = i + side
                        kinds[slot, side], ps[slot, side] = pt_kind[j], pt_p[j]
                        vms[slot, side], ss[slot, side] = pt_vm[j], pt_s[j]
                        copy_into(vs[slot, side], pt_v[j])
                top += _SPLIT
                continue
            if c_s >= 0:
                found, p_fold = _fold_between(tables, branches, a_p, a_s, c_p, c_s)
                if found:
                    return AT_PRESSURE, p_fold, 0.0
                return a_kind, a_p, a_vm
        prev_kind, prev_p, prev_vm, prev_s, prev_v = cur_kind, cur_p, 0.0, cur_s, cur_v
    return NOT_FOUND, 0.0, 0.0
