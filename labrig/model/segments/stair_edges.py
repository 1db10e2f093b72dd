"""The peak and valley of a clean staircase, from its stair edges.

A table rounded to a step q without noise to dither it knows its extremum only to about
a step from the stair values: the top stair holds every row within q / 2 of its value,
and the true peak lies anywhere in that band. Its edges know more: between the last row
of one stair and the first row of the next, a monotone curve crosses the level half-way
between the two stairs (every row is within q / 2 of its stair's value), so each edge is
a point of the curve whose level is exact and whose volume is uncertain only by the gap
between its two rows (a standard error of gap / sqrt(12), uniform within the gap). Two
edges on each side of the extremum give it (a shallow dip, one or two levels deep, has
fewer on its falling side: those, and before a valley the peak's estimate):

- a peak, where the curve is smooth (concave to its top), as the vertex of the
  least-squares quadratic through the four edges;
- a valley, where the braids touch the tube (a corner, which a quadratic would round
  and raise), as the intersection of the lines through the two edges on either side.

Each edge is weighted by 1 / gap^2 (the variance of its volume, in pressure: slope^2 x
gap^2 / 12, the slope nearly the same over two edges). Checked against the analytical
segments at 0.27 and 0.5 kPa every 0.1 mL (docs/explanation/measured-curves.md): the mean error of
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


def _extremum(ve, pe, gap, j: int, fall: int, stair_kpa: float, peak_point=None):
    """(volume, pressure) of the extremum between edges j and j + 1: the peak, or, given
    the peak's (volume, pressure) as ``peak_point``, the valley; ``fall`` is the number
    of edges on the falling branch between them (a shallow dip falls by a level or two:
    then those edges and, before a valley, the peak stand for the falling side)."""
    peak = peak_point is None
    inside = min(EDGES_PER_SIDE, fall)
    left = slice(j - (EDGES_PER_SIDE if peak else inside) + 1, j + 1)
    right = slice(j + 1, j + 1 + (inside if peak else EDGES_PER_SIDE))
    # an estimate off the stair that holds the extremum (a quadratic bent by a narrow
    # top stair, lines nearly parallel) would be clipped to its edge, a drop of up to
    # half a step within a row gap: a fold of its own; the stair's centre is kept instead
    centre = 0.5 * (ve[j] + ve[j + 1])
    if peak:
        both = slice(left.start, right.stop)
        c = np.polyfit(ve[both], pe[both], 2, w=1.0 / gap[both])
        x = -c[1] / (2 * c[0]) if c[0] < 0 else centre
        x = x if ve[j] < x < ve[j + 1] else centre
        y = np.polyval(c, x)
    else:
        x_l, y_l, w_l = ve[left], pe[left], 1.0 / gap[left] ** 2
        if inside < EDGES_PER_SIDE:
            x_l, y_l, w_l = np.r_[peak_point[0], x_l], np.r_[peak_point[1], y_l], np.r_[w_l[0], w_l]
        a_l, b_l = _line(x_l, y_l, w_l)
        a_r, b_r = _line(ve[right], pe[right], 1.0 / gap[right] ** 2)
        x = (b_r - b_l) / (a_l - a_r) if a_l < 0 < a_r else centre
        x = x if ve[j] < x < ve[j + 1] else centre
        y = max(a_l * x + b_l, a_r * x + b_r)  # the corner: the upper of the two lines
    # within the top (bottom) stair's band: beyond its edges' level, within half a step
    # past its value, strictly between its edges
    half = min(abs(stair_kpa - pe[j]), abs(stair_kpa - pe[j + 1]))
    inner = max(pe[j], pe[j + 1]) if peak else min(pe[j], pe[j + 1])
    sign = 1.0 if peak else -1.0
    lo, hi = sorted((inner + sign * _INSIDE * half, stair_kpa + sign * (1 - _INSIDE) * half))
    x_lo, x_hi = ve[j] + _INSIDE * gap[j], ve[j + 1] - _INSIDE * gap[j + 1]
    return float(np.clip(x, x_lo, x_hi)), float(np.clip(y, lo, hi))


def _turns(direction) -> np.ndarray | None:
    """The edges after which a staircase's direction turns, or None where it does not
    start rising (a segment's curve does)."""
    if len(direction) == 0 or direction[0] < 0:
        return None
    return np.flatnonzero(np.diff(direction) != 0)


def shows_dip(v_rows, p_rows) -> bool:
    """Whether the rows are an undithered staircase of a rise-fall-rise curve: their
    stair edges rise, fall and rise again, with no other turn, and with at least
    ``EDGES_PER_SIDE`` rising edges before the peak and after the valley.

    Rounding a monotone curve gives a monotone staircase, so a staircase that never
    flickers between two levels (what noise does where the curve crosses one: up, down
    and up again within a few rows, at every crossing where the curve is flat) falls
    only where the curve falls: a fall of one level is the curve's dip, not rounding.
    Rounding can only hide a dip, one shallower than the step (no level between its
    peak and its valley), and one at least a step deep always shows where rows sample
    its peak and valley (the rounding is monotone, and values a step or more apart
    round to different levels)."""
    _, _, _, direction, _ = stair_edges(v_rows, p_rows)
    turns = _turns(direction)
    return turns is not None and _two_sided(turns, len(direction))


def _two_sided(turns, n_edges: int) -> bool:
    """Two turns (a peak and a valley) with ``EDGES_PER_SIDE`` rising edges before the
    first and after the second."""
    if len(turns) != 2:
        return False
    return turns[0] - EDGES_PER_SIDE + 1 >= 0 and turns[1] + EDGES_PER_SIDE < n_edges


def refine_extrema(v_rows, p_rows, v_curve, p_curve):
    """The curve (v_curve, p_curve) with its peak and valley re-estimated from the
    edges of the staircase (v_rows, p_rows): from the second edge before the peak to
    the second after the valley, the curve is the edges and the two estimates (the
    falling branch between them is its edges, exact level crossings, so that it falls
    from the one to the other however the curve was made from the rows). None where
    the rows are no clean rise-fall-rise staircase (``shows_dip``)."""
    ve, pe, gap, direction, first = stair_edges(v_rows, p_rows)
    turns = _turns(direction)
    if turns is None or not _two_sided(turns, len(ve)):
        return None
    v = np.asarray(v_curve, dtype=float)
    p = np.asarray(p_curve, dtype=float)
    fall = int(turns[1] - turns[0])
    peak_point = None
    for j, peak in zip(turns, (True, False), strict=True):
        stair = float(np.asarray(p_rows)[first[j] + 1])
        x, y = _extremum(ve, pe, gap, j, fall, stair, peak_point)
        peak_point = (x, y)
        before, after = (EDGES_PER_SIDE, fall) if peak else (fall, EDGES_PER_SIDE)
        lo, hi = ve[j - before + 1], ve[j + after]
        window = slice(j - before + 1, j + after + 1)
        keep = (v < lo) | (v > hi)
        v_new = np.r_[v[keep], ve[window], x]
        p_new = np.r_[p[keep], pe[window], y]
        order = np.argsort(v_new, kind="stable")
        v, p = v_new[order], p_new[order]
    return v, p
