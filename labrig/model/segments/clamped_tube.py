"""The paper-numbers tube with its ends held at their radius by the couplings
(docs/decisions/0013).

The SI's tube (S14-S39) is uniform: its ends contract under the braids' force F and
inflate like its middle. The latex tube is glued to the Luer couplings, so its radius
stays R at both ends. This is the axisymmetric neo-Hookean membrane with that end
condition, closed, pushed apart by F, symmetric about mid-length. In the reference arc
length X from the middle (0 <= X <= L_tube/2), with the hoop stretch lambda_2 = r/R, the
meridian's stretch lambda_1 and angle phi to the axis (dz/dX = lambda_1 cos phi, dr/dX =
lambda_1 sin phi), the membrane tensions per deformed length are
T_1 = mu H (lambda_1/lambda_2 - 1/(lambda_1 lambda_2)^3) and T_2 = mu H (lambda_2/lambda_1 -
1/(lambda_1 lambda_2)^3), and equilibrium is

- axial, at every section: 2 pi r T_1 cos phi = F + p pi r^2 (fixes lambda_1: T_1 rises
  with it);
- normal: p = -T_1 (dphi/dX)/lambda_1 + T_2 cos(phi)/r.

With the middle's radius given, phi(0) = 0 and r(L_tube/2) = R fix the shape and the
pressure (``scipy.integrate.solve_bvp``, p an unknown parameter); following the middle's
radius gives the tube's p(v) and l(v). Held at a length by straight braids (record
0014), z(L_tube/2) = l/2 fixes the axial force as a second unknown, the braids' reaction
in place of F. Nothing here is fitted: R, H, mu and F are the segment's. Record 0013
measured with it where the clamped tube peaks against where it meets the strips; the
``paper-clamped:`` library (``labrig.model.segments.paper_clamped``) follows it to its
peak or to the strips.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.integrate import solve_bvp

from labrig.model.segments.braided import KPA_PER_MPA, MM3_PER_ML

# nodes of the first mesh and of the quadratures over the half tube
_NODES = 101
_QUADRATURE_NODES = 2001
_TOLERANCE = 1e-8
# Newton's iterations for lambda_1. T_1 rises and is concave in lambda_1, so from any
# start Newton's first step lands below the root and the rest climb to it without
# overshooting. The start h max(t, 0) + h^-1/2 (h the hoop stretch, t = T_1/(mu H)) lies
# above the root of both of T_1's terms, so it is near the root: ten steps reach it to
# rounding for hoop stretches 0.5-4 and t up to 5, where sixty from a fixed start did.
_NEWTON_STEPS = 10


@dataclass(frozen=True)
class ClampedState:
    """One equilibrium: the pressure, the tube's length, its enclosed volume (not the
    supplied volume: the rest state's is subtracted by ``ClampedTube.supplied_ml``), the
    membrane's energy, the axial force on its ends (F, or the straight braids' reaction
    where its length is held) and the outer radius of its middle (its hoop radius plus
    the thinned wall) at its hoop stretch ``mid_hoop``."""

    p_kpa: float
    l_mm: float
    volume_mm3: float
    energy_mj: float
    force_n: float
    mid_outer_mm: float
    mid_hoop: float


class ClampedTube:
    """The tube of ``segment`` (a ``PaperBraidedSegment``) held at radius R at both ends."""

    def __init__(self, segment):
        self.segment = segment
        self.radius_mm = segment.radius_mm
        self.tension_n_per_mm = segment.shear_modulus_mpa * segment.thickness_mm  # mu H
        self.half_mm = 0.5 * segment.l_tube_mm

    def meridian_stretch(self, hoop, axial_tension):
        """lambda_1 where T_1 = ``axial_tension`` (N/mm) at hoop stretch ``hoop``."""
        hoop = np.asarray(hoop, dtype=float)
        target = np.asarray(axial_tension, dtype=float) / self.tension_n_per_mm
        stretch = hoop * np.maximum(target, 0.0) + hoop**-0.5
        for _ in range(_NEWTON_STEPS):
            f = stretch / hoop - (stretch * hoop) ** -3 - target
            stretch = stretch - f / (1 / hoop + 3 * stretch**-4 * hoop**-3)
        return stretch

    def _force_n(self, p):
        """The axial force: the second unknown where the length is held, else F."""
        return p[1] if len(p) > 1 else self.segment.axial_force_n

    def _stretches(self, y, p):
        r, _, phi = y
        hoop = r / self.radius_mm
        axial = (self._force_n(p) + p[0] * np.pi * r**2) / (2 * np.pi * r)
        return hoop, self.meridian_stretch(hoop, axial / np.cos(phi))

    def _derivatives(self, _x, y, p):
        r, _, phi = y
        hoop, meridian = self._stretches(y, p)
        cube = (meridian * hoop) ** -3
        t1 = self.tension_n_per_mm * (meridian / hoop - cube)
        t2 = self.tension_n_per_mm * (hoop / meridian - cube)
        turn = meridian * (t2 * np.cos(phi) / r - p[0]) / t1
        return np.vstack([meridian * np.sin(phi), meridian * np.cos(phi), turn])

    def solve(self, mid_hoop: float, previous=None, length_mm: float | None = None):
        """The ``solve_bvp`` solution with the middle at hoop stretch ``mid_hoop``, from
        ``previous`` (a neighbouring solution) or a uniform guess; with ``length_mm`` the
        tube is held at that length and the axial force is solved for. Raises ValueError
        where it does not converge."""
        mid_mm = mid_hoop * self.radius_mm
        nodes = np.linspace(0.0, self.half_mm, _NODES)
        if previous is None:
            stretch = 1.0 if length_mm is None else length_mm / (2 * self.half_mm)
            guess = np.vstack([np.full_like(nodes, mid_mm), stretch * nodes, np.zeros_like(nodes)])
            pressure = [0.0]
        else:
            guess, pressure = previous.sol(nodes), list(previous.p[:1])
        if length_mm is not None:
            held = previous is not None and len(previous.p) > 1
            pressure.append(previous.p[1] if held else self.segment.axial_force_n)

        def ends(start, end, p):
            conditions = [start[0] - mid_mm, start[1], start[2], end[0] - self.radius_mm]
            if length_mm is not None:
                conditions.append(end[1] - 0.5 * length_mm)
            return np.array(conditions)

        found = solve_bvp(
            self._derivatives, ends, nodes, guess, p=pressure, tol=_TOLERANCE, max_nodes=20000
        )
        if found.status != 0:
            raise ValueError(f"no clamped equilibrium at a mid hoop stretch of {mid_hoop:.4f}")
        return found

    def state(self, solution) -> ClampedState:
        """Pressure, length, enclosed volume and membrane energy of a solution, by the
        trapezoidal rule on a fine mesh of the half tube (both halves counted)."""
        x = np.linspace(0.0, self.half_mm, _QUADRATURE_NODES)
        y = solution.sol(x)
        p_mpa = float(solution.p[0])
        hoop, meridian = self._stretches(y, solution.p)
        r, z, phi = y
        volume = 2 * np.trapezoid(np.pi * r**2 * meridian * np.cos(phi), x)
        invariant = meridian**2 + hoop**2 + (meridian * hoop) ** -2 - 3
        wall_mm2 = 2 * np.pi * self.radius_mm * self.segment.thickness_mm
        energy = 2 * np.trapezoid(0.5 * self.segment.shear_modulus_mpa * invariant * wall_mm2, x)
        mid_outer = r[0] + self.segment.thickness_mm / (hoop[0] * meridian[0])
        return ClampedState(
            p_mpa * KPA_PER_MPA,
            2 * float(z[-1]),
            float(volume),
            float(energy),
            float(self._force_n(solution.p)),
            float(mid_outer),
            float(hoop[0]),
        )

    def branch(self, mid_hoops) -> list[ClampedState]:
        """The states along increasing mid hoop stretches, each solved from the one before;
        stops (shorter list) where the solver does not converge."""
        states, previous = [], None
        for hoop in mid_hoops:
            try:
                previous = self.solve(float(hoop), previous)
            except ValueError:
                break
            states.append(self.state(previous))
        return states

    @staticmethod
    def supplied_ml(states: list[ClampedState], rest: ClampedState) -> np.ndarray:
        return np.array([s.volume_mm3 - rest.volume_mm3 for s in states]) / MM3_PER_ML
