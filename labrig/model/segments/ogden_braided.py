"""The braided segment with a one-term Ogden membrane: the form of the calibrated library.

The SI's neo-Hookean tube (``labrig.model.segments.braided``) softens little after its
peak: 17 % at most before the braids touch, where the measured segments of the paper
fall far enough for snaps that release up to 10 % of the stored energy (Fig. 4, Movie
S5). A one-term Ogden membrane, W = (2 mu / alpha^2)(l1^alpha + l2^alpha + l3^alpha - 3),
keeps the initial shear modulus mu and, for alpha < 2, softens more and lengthens less
after the peak; alpha = 2 is the neo-Hookean energy S14 itself. Everything else is the
SI's segment: closed ends, the constant braid force F, contact when the tube fills the
braids' envelope, the constrained energy after it (``BraidedSegment.contact_state``).

The SI's closed forms (S37-S39) hold for alpha = 2 only, so before contact the tube is
parametrised by its hoop stretch and the axial equilibrium is solved for the axial
stretch (it is increasing in lambda_z for 1 <= alpha <= 2: a single root, found by
bisection over whole arrays).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np
from scipy.optimize import brentq

from labrig.model.segments.braided import MM3_PER_ML, BraidedSegment, interior_maximum

ALPHA_RANGE = (1.0, 2.0)
# bracket of the axial stretch: the residual is -inf at 0 and positive far out
_LZ_LOW, _LZ_HIGH = 0.05, 50.0
_BISECTIONS = 64


def ogden_energy(stretch_theta, stretch_z, alpha: float):
    """W / mu of the one-term Ogden membrane, lambda_r = 1/(lambda_theta lambda_z)."""
    lt, lz = np.asarray(stretch_theta, dtype=float), np.asarray(stretch_z, dtype=float)
    return 2 / alpha**2 * (lt**alpha + lz**alpha + (lt * lz) ** -alpha - 3)


def ogden_gradient(stretch_theta, stretch_z, alpha: float):
    """(dW/dlambda_theta, dW/dlambda_z) / mu of ``ogden_energy``."""
    lt, lz = np.asarray(stretch_theta, dtype=float), np.asarray(stretch_z, dtype=float)
    cross = (lt * lz) ** -alpha
    return 2 / alpha * (lt**alpha - cross) / lt, 2 / alpha * (lz**alpha - cross) / lz


def axial_residual(stretch_theta, stretch_z, alpha: float, force_stress: float):
    """Axial equilibrium of a closed-end tube under an end force, divided by mu H:
    W_z - lambda_theta W_theta / (2 lambda_z) - F/(2 pi R H mu) (S33 in energy form: the
    pressure on the closed ends, p pi r^2, plus F carried by the wall)."""
    w_theta, w_z = ogden_gradient(stretch_theta, stretch_z, alpha)
    return w_z - stretch_theta * w_theta / (2 * stretch_z) - force_stress


def axial_stretch(stretch_theta, alpha: float, force_stress: float):
    """The axial stretch in equilibrium at each hoop stretch (bisection, 1e-15)."""
    lt = np.asarray(stretch_theta, dtype=float)
    low = np.full(lt.shape, _LZ_LOW)
    high = np.full(lt.shape, _LZ_HIGH)
    for _ in range(_BISECTIONS):
        mid = 0.5 * (low + high)
        above = axial_residual(lt, mid, alpha, force_stress) > 0
        high = np.where(above, mid, high)
        low = np.where(above, low, mid)
    return 0.5 * (low + high)


@dataclass(frozen=True)
class OgdenBraidedSegment(BraidedSegment):
    """``BraidedSegment`` with an Ogden membrane of exponent ``ogden_alpha`` (2: S14).
    Before contact the table parameter runs over the hoop stretch.

    ``contact_compliance`` s >= 1 spreads the stiffening after contact over s times the
    volume: the rigid braids of the SI (s = 1) stop the tube at the envelope's largest
    volume within about a millilitre, where braids that bend outward under the contact
    pressure let it grow further. Each pressure and length of the rigid-braid branch is
    kept, at the supplied volume v_c + s (v - v_c) (v_c at contact), so p(v) stays
    continuous and rises to the same wall pressure."""

    ogden_alpha: float = 2.0
    contact_compliance: float = 1.0

    def __post_init__(self) -> None:
        low, high = ALPHA_RANGE
        if not low <= self.ogden_alpha <= high:
            raise ValueError(f"ogden_alpha must be within {low}..{high}, got {self.ogden_alpha}")
        if not self.contact_compliance >= 1:
            raise ValueError(f"contact_compliance must be >= 1, got {self.contact_compliance}")
        super().__post_init__()

    @property
    def force_stress(self) -> float:
        """F / (2 pi R H mu): the braid force as a membrane stress over mu."""
        return self.force_ratio / 2

    def membrane_gradient(self, stretch_theta, stretch_z):
        return ogden_gradient(stretch_theta, stretch_z, self.ogden_alpha)

    @cached_property
    def lambda_z0(self) -> float:
        """Axial stretch at p = 0: uniaxial tension, lambda_theta^2 lambda_z = 1."""
        return brentq(
            lambda lz: axial_residual(lz**-0.5, lz, self.ogden_alpha, self.force_stress),
            1.0,
            _LZ_HIGH,
            xtol=1e-15,
        )

    @property
    def hoop_stretch0(self) -> float:
        return self.lambda_z0**-0.5

    def hoop_state(self, stretch_theta):
        """(supplied v_ml, p_kpa, l_mm) before contact at hoop stretch lambda_theta:
        p = (mu H / R) W_theta / (lambda_theta lambda_z) (S16 in energy form)."""
        lt = np.asarray(stretch_theta, dtype=float)
        lz = axial_stretch(lt, self.ogden_alpha, self.force_stress)
        w_theta, _ = ogden_gradient(lt, lz, self.ogden_alpha)
        p_kpa = self.pressure_scale_kpa * w_theta / (lt * lz)
        return self.V0_ml * (lt**2 * lz - 1), p_kpa, lz * self.l_tube_mm

    def _gap_mm3(self, stretch_theta):
        v_ml, _, l_mm = self.hoop_state(stretch_theta)
        theta = np.arccos(np.minimum(l_mm / self.l_braid_mm, 1.0))
        return (v_ml + self.V0_ml) * MM3_PER_ML - self.braid_volume_mm3(theta)

    @cached_property
    def contact_hoop_stretch(self) -> float:
        """Hoop stretch at first contact: the tube fills the envelope (S40). Bracketed on
        a grid from the unpressurised state to where the tube is as long as the braids."""
        lt = self.hoop_stretch0 * np.geomspace(1.0, 8.0, 400)[1:]
        _, _, l_mm = self.hoop_state(lt)
        lt = lt[l_mm < self.l_braid_mm * (1 - 1e-9)]
        gap = self._gap_mm3(lt)
        first = int(np.argmax(gap > 0))
        if not gap[first] > 0:
            raise ValueError(f"{self.describe_geometry()}: the tube never reaches the braids")
        low = self.hoop_stretch0 if first == 0 else lt[first - 1]
        return brentq(self._gap_mm3, low * (1 + 1e-12), lt[first], xtol=1e-14)

    @cached_property
    def contact_stretch(self) -> float:
        return float(self.hoop_state(self.contact_hoop_stretch)[2] / self.l_tube_mm)

    @property
    def contact_ml(self) -> float:
        return float(self.hoop_state(self.contact_hoop_stretch)[0])

    @cached_property
    def peak_hoop_stretch(self) -> float | None:
        """Hoop stretch of the pressure peak, or None when contact comes first."""
        return interior_maximum(
            lambda lt: self.hoop_state(lt)[1], self.hoop_stretch0, self.contact_hoop_stretch
        )

    @property
    def peak_stretch(self) -> float | None:
        peak = self.peak_hoop_stretch
        return None if peak is None else float(self.hoop_state(peak)[2] / self.l_tube_mm)

    def peak_knot(self) -> float | None:
        if self.peak_hoop_stretch is None:
            return None
        span = self.contact_hoop_stretch - self.hoop_stretch0
        return (self.peak_hoop_stretch - self.hoop_stretch0) / span

    def _state(self, t):
        """t in [0, 1]: before contact, lambda_theta from p = 0 to contact; t in (1, 2]:
        after contact, theta from the contact angle to the end angle."""
        t = np.asarray(t, dtype=float)
        before = t <= 1
        span = self.contact_hoop_stretch - self.hoop_stretch0
        lt = self.hoop_stretch0 + np.clip(t, 0, 1) * span
        th = self.contact_angle + np.clip(t - 1, 0, 1) * (self.end_angle - self.contact_angle)
        pre, (v_ml, p_kpa, l_mm) = self.hoop_state(lt), self.contact_state(th)
        v_ml = self.contact_ml + self.contact_compliance * (v_ml - self.contact_ml)
        post = (v_ml, p_kpa, l_mm)
        return tuple(np.where(before, a, b) for a, b in zip(pre, post, strict=True))

    def describe_geometry(self) -> str:
        return f"L_braid = {self.l_braid_mm:g} mm, L_tube = {self.l_tube_mm:g} mm"

    def describe(self) -> str:
        return (
            f"braided segment, Ogden membrane (alpha = {self.ogden_alpha:g}, mu = "
            f"{self.shear_modulus_mpa:.3g} MPa), braid envelope radius "
            f"{self.end_radius_mm:.3g} mm, contact compliance {self.contact_compliance:.3g}: "
            f"{self.describe_geometry()}, F = "
            f"{self.axial_force_n:.3f} N; contact at {self.contact_ml:.3f} mL"
        )
