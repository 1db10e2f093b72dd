"""The peak and valley of a clean staircase, from its stair edges.

A table rounded to a step q without noise to dither it knows its extremum only to about
a step from the stair values: the top stair holds every row within q / 2 of its value,
and the true peak lies anywhere in that band. Its edges know more: between the last row
of one stair and the first row of the next, a monotone curve crosses the level half-way
between the two stairs (every row is within q / 2 of its stair's value), so each edge is
a point of the curve whose level is exact and whose volume is uncertain only by the gap
between its two rows (a standard error of gap / sqrt(12), uniform within the gap). Two
edges on each side of the extremum give it:

- a peak, where the curve is smooth (concave to its top), as the vertex of the
  least-squares quadratic through the four edges;
- a valley, where the braids touch the tube (a corner, which a quadratic would round
  and raise), as the intersection of the lines through the two edges on either side.

Each edge is weighted by 1 / gap^2 (the variance of its volume, in pressure: slope^2 x
gap^2 / 12, the slope nearly the same over two edges). Checked against the analytical
segments at 0.27 and 0.5 kPa every 0.1 mL (docs/model.md, section 9): the mean error of
a peak is 0.03-0.07 kPa and of a valley 0.03-0.05 kPa, against 0.07-0.12 kPa for the
stair values.
"""

from __future__ import annotations

import numpy as np

EDGES_PER_SIDE = 2
_INSIDE = 1e-3  # of the half-step: an estimate kept strictly inside its band


def stair_edges(v_ml, p_kpa):
    """The edges of the staircase (v, p): (volume, level, gap, direction, first row)."""
    v = np.asarray(v_ml, dtype=float)
    p = np.asarray(p_kpa, dtype=float)
    i = np.flatnonzero(np.diff(p) != 0)
    return (v[i] + v[i + 1]) / 2, (p[i] + p[i + 1]) / 2, v[i + 1] - v[i], np.sign(np.diff(p)[i]), i


def _line(x, y, w):
    """Weighted least-squares (slope, intercept)."""
    a = np.c_[x, np.ones_like(x)] * np.sqrt(w)[:, None]
    return np.linalg.lstsq(a, y * np.sqrt(w), rcond=None)[0]


def _extremum(ve, pe, gap, j: int, peak: bool, stair_kpa: float):
    """(volume, pressure) of the extremum between edges j and j + 1."""
    left = slice(j - EDGES_PER_SIDE + 1, j + 1)
    right = slice(j + 1, j + 1 + EDGES_PER_SIDE)
    both = slice(left.start, right.stop)
    if peak:
        c = np.polyfit(ve[both], pe[both], 2, w=1.0 / gap[both])
        x = -c[1] / (2 * c[0]) if c[0] < 0 else 0.5 * (ve[j] + ve[j + 1])
        y = np.polyval(c, x)
    else:
        (a_l, b_l), (a_r, b_r) = (_line(ve[s], pe[s], 1.0 / gap[s] ** 2) for s in (left, right))
        x = (b_r - b_l) / (a_l - a_r) if a_l < 0 < a_r else 0.5 * (ve[j] + ve[j + 1])
        y = a_l * x + b_l
    # within the top (bottom) stair's band: beyond its edges' level, within half a step
    # past its value, strictly between its edges
    half = min(abs(stair_kpa - pe[j]), abs(stair_kpa - pe[j + 1]))
    inner = max(pe[j], pe[j + 1]) if peak else min(pe[j], pe[j + 1])
    sign = 1.0 if peak else -1.0
    lo, hi = sorted((inner + sign * _INSIDE * half, stair_kpa + sign * (1 - _INSIDE) * half))
    x_lo, x_hi = ve[j] + _INSIDE * gap[j], ve[j + 1] - _INSIDE * gap[j + 1]
    return float(np.clip(x, x_lo, x_hi)), float(np.clip(y, lo, hi))


def refine_extrema(v_rows, p_rows, v_curve, p_curve):
    """The curve (v_curve, p_curve) with its peak and valley re-estimated from the
    edges of the staircase (v_rows, p_rows): around each, from the second edge before
    it to the second after, the curve is the edges and the estimate. None where the
    rows are no clean rise-fall-rise staircase (their edges must rise, fall and rise
    again, with at least two edges on each side of each extremum)."""
    ve, pe, gap, direction, first = stair_edges(v_rows, p_rows)
    turns = np.flatnonzero(np.diff(direction) != 0)
    if len(turns) != 2 or direction[0] < 0:
        return None
    v = np.asarray(v_curve, dtype=float)
    p = np.asarray(p_curve, dtype=float)
    for j, peak in zip(turns, (True, False), strict=True):
        if j - EDGES_PER_SIDE + 1 < 0 or j + EDGES_PER_SIDE >= len(ve):
            return None
        if peak and turns[1] - turns[0] < EDGES_PER_SIDE:
            return None
        stair = float(np.asarray(p_rows)[first[j] + 1])
        x, y = _extremum(ve, pe, gap, j, peak, stair)
        lo, hi = ve[j - EDGES_PER_SIDE + 1], ve[j + EDGES_PER_SIDE]
        window = slice(j - EDGES_PER_SIDE + 1, j + EDGES_PER_SIDE + 1)
        keep = (v < lo) | (v > hi)
        v_new = np.r_[v[keep], ve[window], x]
        p_new = np.r_[p[keep], pe[window], y]
        order = np.argsort(v_new, kind="stable")
        v, p = v_new[order], p_new[order]
    return v, p
