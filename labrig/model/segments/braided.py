"""The analytical braided fluidic segment of the paper's SI (Eqs. S14–S46), corrected.

A closed-end neo-Hookean latex tube (R, H, mu) is stretched axially by n buckled braids
that push its end couplings apart with a constant force F = 2nK/L_braid (S31, S32).
Before contact the tube is a membrane in equilibrium under the pressure and F (S23,
S34); the braid envelope is a double cone whose half-angle theta follows from
l = L_braid cos(theta) (S41). Contact starts when the tube's volume reaches the volume
the braids enclose (S40); after it the tube fills the envelope, so the supplied volume
fixes theta, the segment shortens as it is inflated further, and the pressure is the
derivative of the total elastic energy along that constrained path (the consistent
form of S42–S46: continuous at first contact, with a wall where the enclosed volume
is maximal). The derivations and every correction to the OCR'd equations are in
docs/explanation/segments.md.

Lengths in mm, forces in N, moduli in MPa; N*mm = mJ, so energies per mm^3 are MPa.
What this module produces is a ``SegmentCurve``; turning names into segments is
``labrig.model.segments.catalog``'s job.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np
from scipy.optimize import brentq, minimize_scalar

from labrig.model.segments.curve import SegmentCurve
from labrig.model.segments.tabulate import tabulate

# The latex tube of the paper (main text and SI).
R_TUBE_MM = 6.35
H_TUBE_MM = 0.79
MU_LATEX_MPA = 0.49

# The table ends on the stiffening wall at this pressure: far above the 0-100 kPa of the
# sensor and the model's pressure grid, so no actuator leaves the table in normal use.
P_END_KPA = 300.0

KPA_PER_MPA = 1000.0
MM3_PER_ML = 1000.0


def braid_force_n(l_braid_mm: float) -> float:
    """Axial force of the buckled braids on the tube, F = 2nK/L_braid (S31) with the
    fitted K of S32, K = L_braid(-0.281 L_braid + 20.4)/(2n): only this combination
    enters, F = 20.4 - 0.281 L_braid (N, L_braid in mm)."""
    return 20.4 - 0.281 * l_braid_mm


def _stretch_cubic(lambda_z, force_ratio):
    """2 lz^3 - F~ lz^2 - 2: zero at the unpressurised stretch (S34 with p = 0)."""
    return 2 * lambda_z**3 - force_ratio * lambda_z**2 - 2


def unpressurised_stretch(force_ratio: float) -> float:
    """Axial stretch of the tube at p = 0 under the braid force (S35, an equality root,
    not a bound), polished by two Newton steps on the cubic it solves."""
    f = force_ratio
    c = np.cbrt(f**3 + 6 * np.sqrt(6) * np.sqrt(f**3 + 54) + 108)
    lam = (c + f * f / c + f) / 6
    for _ in range(2):
        lam -= _stretch_cubic(lam, f) / (6 * lam**2 - 2 * f * lam)
    return float(lam)


def hoop_stretch_sq(lambda_z, force_ratio):
    """lambda_theta^2 on the inflating branch, from S36 (S37 corrected).

    S36 in a = lambda_theta^2 = 1/(lambda_r^2 lambda_z^2) reads
    lz^2 a^2 - B a + 1 = 0 with B = lz^3 (2 lz - F~). The wall thins on inflation
    (lambda_r <= 1), which is the larger root in a. The discriminant B^2 - 4 lz^2 is
    factored as lz * cubic(lz) * (B + 2 lz) so that it is exactly zero at the
    unpressurised stretch instead of a rounding residue.
    """
    lz = np.asarray(lambda_z, dtype=float)
    b = lz**3 * (2 * lz - force_ratio)
    disc = lz * _stretch_cubic(lz, force_ratio) * (b + 2 * lz)
    return (b + np.sqrt(np.maximum(disc, 0.0))) / (2 * lz**2)


def tube_pressure_ratio(lambda_z, force_ratio):
    """pR/(mu H) of the tube at axial stretch lambda_z (S23 = S38):
    1/lz - lambda_r^4 lz with lambda_r^2 = 1/(a lz^2)."""
    lz = np.asarray(lambda_z, dtype=float)
    a = hoop_stretch_sq(lz, force_ratio)
    return 1 / lz - 1 / (a**2 * lz**3)


def envelope_volume_mm3(theta, l_braid_mm: float, end_radius_mm: float):
    """Volume enclosed by braids of length L_braid at half-angle theta (S40): a double
    cone frustum of radius r at the ends and r + (L_braid/2) sin(theta) in the middle."""
    bulge = 0.5 * l_braid_mm * np.sin(theta)
    r = end_radius_mm
    return 2 * np.pi / (3 * np.tan(theta)) * ((r + bulge) ** 3 - r**3)


def envelope_volume_slope(theta, l_braid_mm: float, end_radius_mm: float):
    """d(envelope volume)/d(theta) in mm^3/rad."""
    bulge = 0.5 * l_braid_mm * np.sin(theta)
    r = end_radius_mm
    outer = 3 * (r + bulge) ** 2 * 0.5 * l_braid_mm * np.cos(theta) / np.tan(theta)
    return 2 * np.pi / 3 * (outer - ((r + bulge) ** 3 - r**3) / np.sin(theta) ** 2)


def neo_hookean_gradient(stretch_theta, stretch_z):
    """(dW/dlambda_theta, dW/dlambda_z) / mu of the membrane energy S14 with
    lambda_r = 1/(lambda_theta lambda_z)."""
    inverse = 1 / (stretch_theta * stretch_z) ** 2
    return stretch_theta - inverse / stretch_theta, stretch_z - inverse / stretch_z


def interior_maximum(pressure, lo: float, hi: float) -> float | None:
    """The parameter in (lo, hi) where ``pressure`` peaks (bounded Brent to 1e-12), or
    None when it is highest at ``hi``, the braids' contact: no peak before contact."""
    found = minimize_scalar(
        lambda x: -pressure(x), bounds=(lo, hi), method="bounded", options={"xatol": 1e-12 * hi}
    )
    x = float(found.x)
    interior = x < hi - 1e-9 * (hi - lo)
    return x if interior and pressure(x) > pressure(hi) else None


@dataclass(frozen=True)
class BraidedSegment:
    """A latex tube of length ``l_tube_mm`` inside n braids of length ``l_braid_mm``.

    ``force_n`` overrides the braid force of S31/S32 (0 gives the free tube before
    contact); ``envelope_radius_mm`` is the radius of the braids' envelope at its ends
    (the SI takes the tube's R). Curves are parametrised by the tube's axial stretch
    before contact and by the braid angle after it.
    """

    l_braid_mm: float
    l_tube_mm: float
    radius_mm: float = R_TUBE_MM
    thickness_mm: float = H_TUBE_MM
    shear_modulus_mpa: float = MU_LATEX_MPA
    force_n: float | None = None
    envelope_radius_mm: float | None = None

    def __post_init__(self) -> None:
        for field in ("l_braid_mm", "l_tube_mm", "radius_mm", "thickness_mm"):
            if not getattr(self, field) > 0:
                raise ValueError(f"{field} must be > 0, got {getattr(self, field)}")
        if not self.shear_modulus_mpa > 0 or self.axial_force_n < 0:
            raise ValueError("the shear modulus must be > 0 and the braid force >= 0")
        self.check_braids_enclose_tube()

    def check_braids_enclose_tube(self) -> None:
        """The SI's segment needs buckled braids at p = 0 (ValueError otherwise)."""
        if self.lambda_z0 * self.l_tube_mm >= self.l_braid_mm:
            raise ValueError(
                f"braids of {self.l_braid_mm} mm cannot enclose a tube stretched to "
                f"{self.lambda_z0 * self.l_tube_mm:.2f} mm: they must be longer"
            )

    # --- constants of the segment ----------------------------------------------------
    @property
    def axial_force_n(self) -> float:
        return braid_force_n(self.l_braid_mm) if self.force_n is None else self.force_n

    @property
    def force_ratio(self) -> float:
        """F~ = F/(pi mu H R) (S35)."""
        return self.axial_force_n / (
            np.pi * self.shear_modulus_mpa * self.thickness_mm * self.radius_mm
        )

    @property
    def end_radius_mm(self) -> float:
        """Radius of the braid envelope at the couplings (S40's R)."""
        return self.radius_mm if self.envelope_radius_mm is None else self.envelope_radius_mm

    @property
    def wall_volume_mm3(self) -> float:
        """Volume of the tube's wall that the braids' envelope must also hold at contact:
        none for the SI's thin membrane, which meets the envelope with its own radius."""
        return 0.0

    @property
    def pressure_scale_kpa(self) -> float:
        """mu H / R: the pressure unit of S23-S38."""
        return self.shear_modulus_mpa * self.thickness_mm / self.radius_mm * KPA_PER_MPA

    @cached_property
    def lambda_z0(self) -> float:
        return unpressurised_stretch(self.force_ratio)

    @property
    def V0_ml(self) -> float:
        """Enclosed volume at p = 0. Under the braid force alone the tube is in uniaxial
        tension, lambda_theta^2 lambda_z = 1, so it encloses pi R^2 L_tube, as unstretched."""
        return np.pi * self.radius_mm**2 * self.l_tube_mm / MM3_PER_ML

    # --- before contact --------------------------------------------------------------
    def tube_state(self, lambda_z):
        """(supplied v_ml, p_kpa, l_mm) of the tube at axial stretch lambda_z >= lambda_z0,
        with the braids pushing but not yet touching."""
        lz = np.asarray(lambda_z, dtype=float)
        a = hoop_stretch_sq(lz, self.force_ratio)
        v_ml = self.V0_ml * (a * lz - 1)  # enclosed pi R^2 L a lz (S39 corrected) - V0
        p_kpa = tube_pressure_ratio(lz, self.force_ratio) * self.pressure_scale_kpa
        return v_ml, p_kpa, lz * self.l_tube_mm

    def braid_volume_mm3(self, theta):
        """Volume enclosed by the braids at half-angle theta (S40)."""
        return envelope_volume_mm3(theta, self.l_braid_mm, self.end_radius_mm)

    def _braid_volume_slope(self, theta):
        return envelope_volume_slope(theta, self.l_braid_mm, self.end_radius_mm)

    def _angle(self, lambda_z):
        return np.arccos(np.asarray(lambda_z) * self.l_tube_mm / self.l_braid_mm)  # S41

    @cached_property
    def contact_stretch(self) -> float:
        """Axial stretch at first contact: the tube's volume reaches the braids' (S40)."""
        lam_straight = self.l_braid_mm / self.l_tube_mm  # braids straight: theta = 0

        def gap_mm3(lz):
            enclosed = (self.tube_state(lz)[0] + self.V0_ml) * MM3_PER_ML
            return enclosed - self.braid_volume_mm3(self._angle(lz))

        # At lambda_z0 the cone encloses more than the tube; as the braids straighten
        # their volume tends to pi R^2 l, less than the inflated tube's.
        return brentq(gap_mm3, self.lambda_z0, lam_straight * (1 - 1e-12), xtol=1e-14)

    @property
    def contact_angle(self) -> float:
        return float(self._angle(self.contact_stretch))

    @property
    def contact_ml(self) -> float:
        """Supplied volume at first contact."""
        return float(self.tube_state(self.contact_stretch)[0])

    @cached_property
    def peak_stretch(self) -> float | None:
        """Axial stretch of the pressure peak, or None when contact comes first."""
        return interior_maximum(
            lambda lz: tube_pressure_ratio(lz, self.force_ratio),
            self.lambda_z0,
            self.contact_stretch,
        )

    # --- after contact ---------------------------------------------------------------
    def membrane_gradient(self, stretch_theta, stretch_z):
        """dW/dlambda per unit shear modulus: the neo-Hookean latex of S14."""
        return neo_hookean_gradient(stretch_theta, stretch_z)

    @cached_property
    def wall_angle(self) -> float:
        """Braid angle at which the enclosed volume is largest: the volume cannot grow
        past it, so the pressure diverges there (the stiffening wall)."""
        return brentq(self._braid_volume_slope, self.contact_angle, 0.5 * np.pi - 1e-6)

    def contact_state(self, theta):
        """(supplied v_ml, p_kpa, l_mm) after contact, at braid angle theta between the
        contact angle and the wall angle.

        The tube fills the envelope: V = braid volume (less the tube's wall, where it has
        one: ``wall_volume_mm3``), l = L_braid cos(theta),
        lambda_theta^2 = V/(pi R^2 l). The pressure is dPi/dV along this path, Pi the
        tube's membrane energy (``membrane_gradient``, thin membrane) plus the braids'
        energy F (L_braid - l) of a constant force F (S31).
        """
        th = np.asarray(theta, dtype=float)
        r, lt, lb = self.radius_mm, self.l_tube_mm, self.l_braid_mm
        enclosed = self.braid_volume_mm3(th) - self.wall_volume_mm3
        d_enclosed = self._braid_volume_slope(th)
        length = lb * np.cos(th)
        d_length = -lb * np.sin(th)
        stretch_z = length / lt
        d_stretch_z = d_length / lt
        a = enclosed / (np.pi * r**2 * length)  # lambda_theta^2
        d_a = (d_enclosed * length - enclosed * d_length) / (np.pi * r**2 * length**2)
        stretch_theta = np.sqrt(a)
        w_theta, w_z = self.membrane_gradient(stretch_theta, stretch_z)
        wall_mm3 = 2 * np.pi * r * self.thickness_mm * lt  # undeformed membrane
        d_stretch_theta = d_a / (2 * stretch_theta)
        d_tube = self.shear_modulus_mpa * wall_mm3 * (w_theta * d_stretch_theta + w_z * d_stretch_z)
        d_braids = -self.axial_force_n * d_length
        p_kpa = (d_tube + d_braids) / d_enclosed * KPA_PER_MPA
        return enclosed / MM3_PER_ML - self.V0_ml, p_kpa, length

    @cached_property
    def end_angle(self) -> float:
        """Braid angle at which the wall reaches P_END_KPA: where the table ends."""
        return brentq(
            lambda th: self.contact_state(th)[1] - P_END_KPA,
            self.contact_angle,
            self.wall_angle - 1e-9,
            xtol=1e-13,
        )

    # --- the table -------------------------------------------------------------------
    def _state(self, t):
        """t in [0, 1]: before contact, lambda_z from lambda_z0 to contact; t in (1, 2]:
        after contact, theta from the contact angle to the end angle."""
        t = np.asarray(t, dtype=float)
        before = t <= 1
        lz = self.lambda_z0 + np.clip(t, 0, 1) * (self.contact_stretch - self.lambda_z0)
        th = self.contact_angle + np.clip(t - 1, 0, 1) * (self.end_angle - self.contact_angle)
        pre, post = self.tube_state(lz), self.contact_state(th)
        return tuple(np.where(before, a, b) for a, b in zip(pre, post, strict=True))

    def peak_knot(self) -> float | None:
        """The table parameter t of the pressure peak (``_state``), None without a peak."""
        if self.peak_stretch is None:
            return None
        return (self.peak_stretch - self.lambda_z0) / (self.contact_stretch - self.lambda_z0)

    def describe(self) -> str:
        return (
            f"analytical braided segment (SI S14-S46, corrected): L_braid = "
            f"{self.l_braid_mm:g} mm, L_tube = {self.l_tube_mm:g} mm, F = "
            f"{self.axial_force_n:.3f} N; contact at {self.contact_ml:.3f} mL"
        )

    def curve(self, name: str | None = None) -> SegmentCurve:
        """The segment's p(v), l(v) from the unpressurised state to P_END_KPA."""
        knots = [np.linspace(0, 1, 33), np.linspace(1, 2, 33)[1:]]
        if self.peak_knot() is not None:
            knots.append([self.peak_knot()])
        _, v, p, length = tabulate(self._state, np.unique(np.concatenate(knots)))
        v[0], p[0] = 0.0, 0.0  # the unpressurised state, exactly (not a rounding residue)
        label = name or f"B{self.l_braid_mm:g}-T{self.l_tube_mm:g}"
        return SegmentCurve(label, v, p, length, V0_ml=self.V0_ml, source=self.describe())
