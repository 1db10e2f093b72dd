"""The Gent spherical membrane of the SI's "Analytical Exploration" (Eqs. S1-S9).

A thin incompressible balloon of radius R, thickness H and shear modulus mu whose
material stiffens towards a locking stretch set by J_m. Its p(v) has the rise, fall and
final rise that makes interconnected membranes snap (Figs. S1, S2), which makes it the
smallest test case of the actuator model. The paper gives no value for J_m; membranes
a, b, c are those of Fig. S1 with J_m,a = 28.5, chosen so that the three pairs of
Fig. S2 behave as the paper describes (docs/explanation/segments.md: a+b all stable, b+c one snap,
a+c two snaps with the second flowing back; the window is about 27.5 < J_m,a < 29.8).

Units: R = 10 mm, H_a = 1 mm, mu = 0.5 MPa (pressure scale mu H/R = 50 kPa, peaks
60-75 kPa like the braided segments); the segment's "length" is the diameter 2 r.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cache, cached_property

import numpy as np

from labrig.model.segments.curve import SegmentCurve
from labrig.model.segments.tabulate import tabulate

R_SPHERE_MM = 10.0
H_A_MM = 1.0
MU_SPHERE_MPA = 0.5
J_M_A = 28.5
# Fig. S1: (H / H_a, J_m / J_m,a) of membranes a, b, c
MEMBRANES = {"a": (1.0, 1.0), "b": (1.1, 0.9), "c": (1.05, 1.2)}
GENT_NAMES = tuple(f"gent-{letter}" for letter in MEMBRANES)

# As for the braided segments: the table ends on the stiffening branch at this pressure.
P_END_KPA = 300.0


def gent_pressure_ratio(stretch, j_m: float):
    """pR/(mu H) of the inflated sphere at hoop stretch lambda (S8; it follows from
    sigma = lambda dW/dlambda of the Gent energy S6 and sigma = p r/(2h), h = H/lambda^2)."""
    lam = np.asarray(stretch, dtype=float)
    return 2 * j_m / lam**3 * (lam**6 - 1) / (-1 + lam**4 * (3 + j_m) - 2 * lam**6)


def gent_density(invariant_excess, j_m: float):
    """Gent's energy per reference volume over mu, -(J_m/2) ln(1 - (I1 - 3)/J_m), and
    its stiffening factor 1/(1 - (I1 - 3)/J_m) (its slope over neo-Hookean's), at
    ``invariant_excess`` = I1 - 3; locked (infinite) from I1 - 3 = J_m on."""
    share = np.minimum(np.asarray(invariant_excess) / j_m, 1.0)
    with np.errstate(divide="ignore"):
        return -0.5 * j_m * np.log1p(-share), 1 / (1 - share)


def lock_stretch(j_m: float) -> float:
    """Stretch at which the Gent energy diverges: 2 lambda^2 + lambda^-4 - 3 = J_m."""
    from scipy.optimize import brentq  # here: a segment name is checked against GENT_NAMES

    return brentq(lambda lam: 2 * lam**2 + lam**-4 - 3 - j_m, 1.0, np.sqrt(j_m + 3))


@dataclass(frozen=True)
class GentSphere:
    """A Gent balloon; ``curve`` tabulates it from the unpressurised state."""

    radius_mm: float = R_SPHERE_MM
    thickness_mm: float = H_A_MM
    shear_modulus_mpa: float = MU_SPHERE_MPA
    j_m: float = J_M_A

    @property
    def V0_ml(self) -> float:
        return 4 / 3 * np.pi * self.radius_mm**3 / 1000

    def state(self, stretch):
        """(supplied v_ml, p_kpa, diameter l_mm) at hoop stretch lambda (S8, S9)."""
        lam = np.asarray(stretch, dtype=float)
        scale_kpa = self.shear_modulus_mpa * self.thickness_mm / self.radius_mm * 1000
        return (
            self.V0_ml * (lam**3 - 1),
            gent_pressure_ratio(lam, self.j_m) * scale_kpa,
            2 * self.radius_mm * lam,
        )

    @cached_property
    def end_stretch(self) -> float:
        """Stretch where the stiffening branch reaches P_END_KPA, just short of the lock."""
        from scipy.optimize import brentq

        lock = lock_stretch(self.j_m)
        start = self.extremum_stretches[-1] if self.extremum_stretches else 1.0
        return brentq(lambda lam: self.state(lam)[1] - P_END_KPA, start, lock * (1 - 1e-12))

    @cached_property
    def extremum_stretches(self) -> tuple[float, ...]:
        """Stretches of the pressure peak and valley (empty for small J_m, where p(v)
        only rises), located on a grid and refined to 1e-12."""
        from scipy.optimize import minimize_scalar

        lam = np.linspace(1.0, lock_stretch(self.j_m), 4001)[:-1]
        p = gent_pressure_ratio(lam, self.j_m)
        turns = np.flatnonzero(np.diff(np.sign(np.diff(p)))) + 1
        found = []
        for i in turns:
            sign = 1.0 if p[i] > p[i - 1] else -1.0  # maximise at a peak, minimise at a valley
            res = minimize_scalar(
                lambda x, s=sign: -s * gent_pressure_ratio(x, self.j_m),
                bounds=(lam[i - 1], lam[i + 1]),
                method="bounded",
                options={"xatol": 1e-12},
            )
            found.append(float(res.x))
        return tuple(found)

    def curve(self, name: str = "gent") -> SegmentCurve:
        knots = np.unique(
            np.concatenate([np.linspace(1.0, self.end_stretch, 65), self.extremum_stretches])
        )
        _, v, p, length = tabulate(self.state, knots)
        return SegmentCurve(
            name,
            v,
            p,
            length,
            V0_ml=self.V0_ml,
            source=(
                f"Gent sphere (SI S6-S9): R = {self.radius_mm:g} mm, H = {self.thickness_mm:g} mm, "
                f"mu = {self.shear_modulus_mpa:g} MPa, J_m = {self.j_m:g}"
            ),
        )


@cache
def gent_membrane(name: str) -> SegmentCurve:
    """Membrane a, b or c of Fig. S1 by name (``gent-a``, ``gent-b``, ``gent-c``)."""
    h_ratio, j_ratio = MEMBRANES[name.removeprefix("gent-")]
    sphere = GentSphere(thickness_mm=H_A_MM * h_ratio, j_m=J_M_A * j_ratio)
    return sphere.curve(name)
