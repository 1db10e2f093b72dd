"""The blocked actuator: the reaction force when the ends are held at a fixed distance.

With the length free, each segment's state is its volume and the actuator follows the
path of Eq. 4's energy. Held between the grips of a testing machine, the segments must
also share the fixed total length L_b. Each segment resists a change of its length at
constant volume with an axial stiffness k_i (``axial_stiffness_n_per_mm``), so

    E(v_1..v_n) = sum_i E_i(v_i) + (sum_i l_i(v_i) + fittings - L_b)^2 / (2 sum_i 1/k_i)

is the energy with the length constraint (the segments' lengths eliminated at their
optimum, l_i - l_i(v_i) = -F/k_i), and the grips feel the force

    F = (sum_i l_i(v_i) + fittings - L_b) / sum_i 1/k_i     (compression positive).

Its equilibria have p_i(v_i) + F dl_i/dv_i equal in every segment; that common value is
the pressure. The path under volume control follows the overdamped flow
dv_i/dt = -(dE/dv_i - mean_j dE/dv_j) from the previous state to the next minimum, the
physical reference for where a snap ends (with equal resistances it is what the fluid
does), one volume increment at a time; Newton's method finds the same minimum faster
wherever it stays within two increments of the last state, and the flow takes over
where it does not (a snap).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from scipy.integrate import solve_ivp

from labrig.model.segments.curve import SegmentCurve

# The latex tube of the paper's segments: Young's modulus 3 mu (MPa) and wall area
# 2 pi R H (mm^2), so E A / l is in N/mm.
LATEX_YOUNG_MPA = 3 * 0.49
LATEX_WALL_AREA_MM2 = 2 * np.pi * 6.35 * 0.79


def axial_stiffness_n_per_mm(curve: SegmentCurve) -> float:
    """A segment's stiffness against a change of its length at constant volume: the
    latex wall in tension, E A / l0 (the buckled braids push with a constant force and
    add none)."""
    return LATEX_YOUNG_MPA * LATEX_WALL_AREA_MM2 / float(curve.l_mm[0])


@dataclass(frozen=True)
class BlockedPath:
    """The blocked actuator under volume-controlled inflation, one row per volume; a
    snap shows as two rows at the same volume."""

    v_ml: np.ndarray
    p_kpa: np.ndarray
    force_n: np.ndarray
    v_i_ml: np.ndarray  # (rows, n)

    def snaps(self, min_jump_n: float = 0.0) -> list[tuple[float, float, float]]:
        """(volume, force before, force after) of each snap (repeated volume)."""
        same = np.flatnonzero(np.diff(self.v_ml) == 0)
        return [
            (float(self.v_ml[i]), float(self.force_n[i]), float(self.force_n[i + 1]))
            for i in same
            if abs(self.force_n[i + 1] - self.force_n[i]) >= min_jump_n
        ]


class BlockedActuator:
    """Segments in series between fixed grips, at their unpressurised total length."""

    def __init__(
        self,
        segments: Sequence[SegmentCurve],
        fittings_length_mm: float = 0.0,
        stiffness_n_per_mm: Sequence[float] | None = None,
    ):
        self.segments = tuple(segments)
        self.fittings_length_mm = float(fittings_length_mm)
        if stiffness_n_per_mm is None:
            stiffness_n_per_mm = [axial_stiffness_n_per_mm(s) for s in segments]
        self.compliance_mm_per_n = sum(1.0 / k for k in stiffness_n_per_mm)
        self.l_blocked_mm = self.free_length_mm(np.zeros(len(segments)))

    def free_length_mm(self, v_i) -> float:
        """The length the segments would take at volumes ``v_i`` if let go."""
        lengths = (float(s.length_mm(v)) for s, v in zip(self.segments, v_i, strict=True))
        return sum(lengths) + self.fittings_length_mm

    def force_n(self, v_i) -> float:
        """The grips' reaction force (N, compression positive) at volumes ``v_i``."""
        return (self.free_length_mm(v_i) - self.l_blocked_mm) / self.compliance_mm_per_n

    def energy_mj(self, v_i) -> float:
        """Eq. 4's energy plus the length constraint's (N mm = mJ)."""
        elastic = sum(float(s.energy_mj(v)) for s, v in zip(self.segments, v_i, strict=True))
        return elastic + 0.5 * self.force_n(v_i) ** 2 * self.compliance_mm_per_n

    def gradient_kpa(self, v_i) -> np.ndarray:
        """dE/dv_i = p_i(v_i) + F dl_i/dv_i (kPa; N mm/mL = kPa)."""
        force = self.force_n(v_i)
        return np.array(
            [
                float(s.pressure_kpa(v)) + force * _length_slope(s, v)
                for s, v in zip(self.segments, v_i, strict=True)
            ]
        )

    def relax(self, v_i: np.ndarray, tol_kpa: float = 1e-7) -> np.ndarray:
        """The minimum the overdamped flow at constant total volume reaches from ``v_i``."""
        if len(v_i) == 1:
            return v_i

        def flow(_t, v):
            g = self.gradient_kpa(v)
            return -(g - g.mean())

        def settled(_t, v):
            g = self.gradient_kpa(v)
            return float(np.max(np.abs(g - g.mean()))) - tol_kpa

        settled.terminal = True
        solution = solve_ivp(
            flow, (0.0, 1e5), v_i, method="LSODA", events=settled, rtol=1e-10, atol=1e-12
        )
        return solution.y[:, -1]

    def newton(self, start: np.ndarray, max_move_ml: float) -> np.ndarray | None:
        """The stable equilibrium near ``start`` at its total volume by Newton's method,
        or None when there is none within ``max_move_ml`` (a snap: the flow decides)."""
        n = len(start)
        if n == 1:
            return start
        free = start[:-1].copy()
        total = float(start.sum())

        def full(x):
            return np.append(x, total - x.sum())

        def residual(x):
            g = self.gradient_kpa(full(x))
            return g[:-1] - g[-1]

        h = 1e-6
        for _ in range(20):
            r = residual(free)
            hessian = np.empty((n - 1, n - 1))
            for j in range(n - 1):
                step = np.zeros(n - 1)
                step[j] = h
                hessian[:, j] = (residual(free + step) - residual(free - step)) / (2 * h)
            try:
                dx = np.linalg.solve(hessian, -r)
            except np.linalg.LinAlgError:
                return None
            free = free + dx
            if np.max(np.abs(full(free) - start)) > max_move_ml:
                return None
            if np.max(np.abs(dx)) < 1e-10:
                symmetric = 0.5 * (hessian + hessian.T)
                return full(free) if np.all(np.linalg.eigvalsh(symmetric) > 0) else None
        return None

    def path(self, v_max_ml: float, dv_ml: float = 0.05) -> BlockedPath:
        """Inflation from 0 to ``v_max_ml``: each increment shared equally, then relaxed;
        a state that moved by more than the increment snapped and gets two rows."""
        n = len(self.segments)
        state = np.zeros(n)
        rows_v, rows_p, rows_f, rows_vi = [], [], [], []

        def record(v, s):
            g = self.gradient_kpa(s)
            rows_v.append(v)
            rows_p.append(float(g.mean()))
            rows_f.append(self.force_n(s))
            rows_vi.append(s.copy())

        record(0.0, state)
        for v in np.arange(dv_ml, v_max_ml + 0.5 * dv_ml, dv_ml):
            start = state + (v - state.sum()) / n
            relaxed = self.newton(start, 2 * dv_ml)
            if relaxed is None:
                relaxed = self.relax(start)
            if np.max(np.abs(relaxed - start)) > 2 * dv_ml:
                # the state it left, at the new volume, and where it went: the snap
                record(float(v), start)
            state = relaxed
            record(float(v), state)
        return BlockedPath(np.array(rows_v), np.array(rows_p), np.array(rows_f), np.array(rows_vi))


def _length_slope(segment: SegmentCurve, v_ml: float, h: float = 1e-4) -> float:
    """dl/dv (mm/mL) by a central difference of the PCHIP length (zero past the table)."""
    return float(segment.length_mm(v_ml + h) - segment.length_mm(v_ml - h)) / (2 * h)
