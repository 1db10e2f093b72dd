"""The inflation path from the equilibria on a pressure grid (the paper's operational
method, Fig. S5), kept as a baseline for the benchmark: how accurate a grid is, and at
what cost, next to the continuation of ``labrig.model.actuator.path``.

``Actuator.equilibria`` gives every equilibrium at every grid pressure, grouped here by
branch combination (on one combination each segment is a function of p, so its grid
points form one curve). The path follows the stable points of a combination in the
direction in which the total volume grows, and at the end of the stretch:

- if the combination ends (a segment reached an extremum of its curve between two grid
  pressures) and the combination with that segment on its next branch is stable at the
  same grid pressure, the path changes combination there (a stable transition when the
  number of segments right of their peak changes);
- otherwise (v turns back, the next point is unstable, or no stable way on) the state
  is lost at the volume of the last grid point: the actuator snaps, at that volume, to
  the stable equilibrium nearest along the way the path was moving (interpolated between
  grid points). For two segments that is where the flow goes; for more it is the
  nearest-minimum choice a local minimiser makes.

Everything is known to the grid spacing only: a fold's volume to second order in it (v is
stationary there), a peak crossing's to its square root (v ~ sqrt(p_peak - p) near a
peak), and a dip shallower than the spacing is not seen at all.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass

import numpy as np

from labrig.model.actuator.equilibria import Actuator


@dataclass(frozen=True)
class GridTransition:
    v_ml: float  # total volume of the last grid point before it
    alpha: int
    beta: int
    stable: bool
    v_i_pre_ml: tuple[float, ...]
    v_i_post_ml: tuple[float, ...]


@dataclass
class _Combination:
    branches: tuple[int, ...]
    grid_index: np.ndarray  # (m,) ascending
    v_i: np.ndarray  # (m, n)
    stable: np.ndarray  # (m,)

    @property
    def v(self) -> np.ndarray:
        return self.v_i.sum(axis=1)


def grid_path(
    actuator: Actuator, v_end_ml: float, *, n_points: int = 1000, p_max_kpa: float = 100.0
) -> list[GridTransition]:
    """The transitions met while inflating from 0 to ``v_end_ml``, seen on an equispaced
    grid of ``n_points`` pressures from 0 to ``p_max_kpa``."""
    grid = actuator.pressure_grid(n_points, p_max_kpa)
    found = actuator.equilibria(grid)
    index = np.searchsorted(grid, found.p_kpa)
    combos: dict[tuple[int, ...], _Combination] = {}
    keys = [tuple(int(b) for b in row) for row in found.branches]
    for key in dict.fromkeys(keys):
        rows = np.flatnonzero(np.all(found.branches == key, axis=1))
        rows = rows[np.argsort(index[rows])]
        combos[key] = _Combination(key, index[rows], found.v_i_ml[rows], found.stable[rows])
    branches = [s.branches for s in actuator.segments]

    def direction_of(key: tuple[int, ...]) -> int:
        # p rises with v unless one segment is on a falling branch (then stable states
        # need dv/dp < 0)
        return 1 if all(branches[i][b].rising for i, b in enumerate(key)) else -1

    out: list[GridTransition] = []
    key = tuple(0 for _ in actuator.segments)
    pos = 0
    for _ in range(100 * len(actuator.segments) + 100):
        combo = combos[key]
        s = direction_of(key)
        v = combo.v
        while True:
            nxt = pos + s
            inside = 0 <= nxt < len(v) and combo.grid_index[nxt] == combo.grid_index[pos] + s
            if not inside or not combo.stable[nxt] or v[nxt] <= v[pos]:
                break
            if v[nxt] >= v_end_ml:
                return out
            pos = nxt
        g = int(combo.grid_index[pos])
        if not inside and not 0 <= g + s < n_points:
            return out  # the grid ends before v_end_ml
        pre = combo.v_i[pos]
        alpha = actuator.alpha(key)
        crossing = None
        if not inside:
            low, high = sorted((grid[g], grid[g + s]))
            ran_out = [
                i
                for i, b in enumerate(key)
                if low <= (branches[i][b].p_hi_kpa if s > 0 else branches[i][b].p_lo_kpa) <= high
            ]
            crossing = _cross(combos, key, g, s, v[pos], ran_out, branches, direction_of)
        if crossing is not None:
            key, pos = crossing
            beta = actuator.alpha(key)
            if beta != alpha:
                post = combos[key].v_i[pos]
                out.append(GridTransition(float(pre.sum()), alpha, beta, True, _t(pre), _t(post)))
            continue
        previous = combo.v_i[pos - s] if 0 <= pos - s < len(v) else pre
        key, pos, post = _snap(combos, key, pos, pre - previous)
        out.append(
            GridTransition(float(pre.sum()), alpha, actuator.alpha(key), False, _t(pre), _t(post))
        )
    raise RuntimeError(f"the grid path does not end: {actuator.names}")


def _t(values) -> tuple[float, ...]:
    return tuple(float(x) for x in values)


def _cross(combos, key, g, s, v_pre, ran_out, branches, direction_of):
    """The stable combination with some of the segments that ran out of branch (between
    grid points g and g + s) switched, at grid point g or g + s, with at least the
    volume of the point left and v growing on it; None if there is none.

    As in ``labrig.model.actuator.path``: moving in pressure direction s, a segment on a rising
    branch with s > 0 (a falling one with s < 0) goes on to the next branch, otherwise
    back to the previous one; a branch whose whole pressure range lies between two grid
    points (a dip shallower than the spacing) is hopped over.
    """
    options = []
    for i in ran_out:
        step = 1 if branches[i][key[i]].rising == (s > 0) else -1
        reachable = [b for b in (key[i] + step, key[i] + 2 * step) if 0 <= b < len(branches[i])]
        options.append([(i, b) for b in reachable])
    best = None
    for size in range(1, len(ran_out) + 1):
        for subset in itertools.combinations(options, size):
            for switches in itertools.product(*subset):
                other = list(key)
                for i, b in switches:
                    other[i] = b
                other = tuple(other)
                combo = combos.get(other)
                if combo is None:
                    continue
                v = combo.v
                for grid_point in (g, g + s):
                    at = np.flatnonzero(combo.grid_index == grid_point)
                    if len(at) == 0 or not combo.stable[at[0]] or v[at[0]] < v_pre:
                        continue
                    pos = int(at[0])
                    nxt = pos + direction_of(other)
                    if not (0 <= nxt < len(v) and combo.stable[nxt] and v[nxt] > v[pos]):
                        continue
                    if best is None or v[pos] < best[0]:
                        best = (v[pos], other, pos)
    return None if best is None else (best[1], best[2])


def _snap(combos, key, pos, tangent):
    """The stable state at the same total volume nearest along ``tangent`` (the way the
    path moved into the fold); the position to go on from is the grid point of that
    interval on which v is larger."""
    pre = combos[key].v_i[pos]
    v_star = pre.sum()
    u = tangent - tangent.mean()
    candidates = []
    for other, combo in combos.items():
        v = combo.v
        ok = combo.stable[:-1] & combo.stable[1:] & (np.diff(combo.grid_index) == 1)
        lo, hi = np.minimum(v[:-1], v[1:]), np.maximum(v[:-1], v[1:])
        for j in np.flatnonzero(ok & (lo <= v_star) & (v_star <= hi) & (hi > lo)):
            if other == key and pos in (j, j + 1):
                continue  # the point the path is leaving
            w = (v_star - v[j]) / (v[j + 1] - v[j])
            state = combo.v_i[j] + w * (combo.v_i[j + 1] - combo.v_i[j])
            ahead = float(np.dot(state - pre, u)) > 0
            distance = float(np.linalg.norm(state - pre))
            go_on = j + 1 if v[j + 1] > v[j] else j
            candidates.append((not ahead, distance, other, go_on, state))
    if not candidates:
        raise RuntimeError(f"no stable state at v = {v_star:.4f} mL on the grid")
    _, _, other, go_on, state = min(candidates, key=lambda c: (c[0], c[1]))
    return other, go_on, state
