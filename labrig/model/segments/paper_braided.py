"""The SI's braided segment built from the paper's numbers, tubing read as diameters.

The paper gives the latex tube as "inner radius R = 6.35 mm, thickness H = 0.79 mm" and
the braid tubing as "inner radius of 7.94 mm and a thickness of 1.59 mm": 1/4", 1/32",
5/16" and 1/16", the sizes tubing is sold by (its inner diameter). Read as diameters the
latex tube's inner radius is 3.175 mm and its outer radius 3.965 mm, the braid tubing's
inner radius (3.97 mm): the braid tube slides snugly over the latex one. With the
paper's mu = 0.49 MPa, F = 20.4 - 0.281 L_braid (S31, S32) and nothing fitted the SI's
tube peaks at 62.8-70.9 kPa, the paper's 65-85 kPa range, rising with L_braid.

Two things about the braids that the SI's contact (S40-S46) leaves out decide whether
a segment can be built at all (docs/explanation/segments.md derives both):

- The braids are inextensible strips of length L_braid: the segment can never be
  longer than L_braid. The tube is thin, and the braid force stretches it by 40-60 % at
  p = 0; where L_tube times that stretch exceeds L_braid the braids straighten
  (theta = 0) and hold the tube at l = L_braid with less than F. The tube then inflates
  at that fixed length (hoop equilibrium S23 with lambda_z = L_braid / L_tube) until it
  meets the straight braids. The SI's segment cannot represent this (its contact angle
  S41 has no solution), which is why six short-braid, long-tube segments fail there.
- The tube meets the braids with its outer surface, and the braids' envelope starts at
  the braid tubing's inner radius (the strips are cut from it and bow outwards from
  their uncut ends): contact is when the tube's inner volume plus its wall's
  (incompressible) volume fills the envelope of S40 with end radius 3.97 mm. Four more
  segments reach straight braids before that volume: they meet them at theta = 0, on
  the fixed-length branch above.

After contact the SI's constrained energy (``BraidedSegment.contact_state``) holds,
starting at theta = 0 for a segment that met straight braids.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np
from scipy.optimize import brentq

from labrig.model.segments.braided import (
    MM3_PER_ML,
    BraidedSegment,
    hoop_stretch_sq,
    interior_maximum,
)
from labrig.model.segments.curve import SegmentCurve
from labrig.model.segments.tabulate import tabulate

# Tubing sold by its inner diameter (paper, Materials): the latex tube 1/4" x 1/32", the
# braid tubing 5/16" x 1/16".
TUBE_INNER_RADIUS_MM = 3.175
TUBE_THICKNESS_MM = 0.79
BRAID_INNER_RADIUS_MM = 3.97
# The first braid angle of the contact branch when the tube meets straight braids: S40
# is 0/0 at theta = 0; 1e-4 rad changes the enclosed volume by about 1e-3 mm^3.
STRAIGHT_ANGLE = 1e-4
_SAMPLES = 33


def capped_pressure_ratio(stretch_theta, stretch_z):
    """pR/(mu H) of a tube held at axial stretch lambda_z (S23 with lambda_r =
    1/(lambda_theta lambda_z)): 1/lz - 1/(lt^4 lz^3), rising with the hoop stretch."""
    lt, lz = np.asarray(stretch_theta, dtype=float), np.asarray(stretch_z, dtype=float)
    return 1 / lz - 1 / (lt**4 * lz**3)


@dataclass(frozen=True)
class PaperBraidedSegment(BraidedSegment):
    """``BraidedSegment`` with inextensible braids and contact at the tube's outer
    surface (module docstring). Three branches, each tabulated on its own parameter:
    the free tube under F (axial stretch), the tube held at L_braid by straight braids
    (hoop stretch), the tube filling the braids (braid angle); either of the first two
    may be empty."""

    radius_mm: float = TUBE_INNER_RADIUS_MM
    thickness_mm: float = TUBE_THICKNESS_MM
    envelope_radius_mm: float | None = BRAID_INNER_RADIUS_MM

    def check_braids_enclose_tube(self) -> None:
        """Inextensible braids hold any tube that F alone would stretch past them."""

    @property
    def wall_volume_mm3(self) -> float:
        """The latex wall, pi ((R + H)^2 - R^2) L_tube: incompressible, so the same at
        every stretch."""
        r, h = self.radius_mm, self.thickness_mm
        return np.pi * ((r + h) ** 2 - r**2) * self.l_tube_mm

    @property
    def cap_stretch(self) -> float:
        """The axial stretch at which the tube is as long as the straight braids."""
        return self.l_braid_mm / self.l_tube_mm

    @property
    def straight_at_rest(self) -> bool:
        """Whether F alone would stretch the tube past L_braid: the braids are straight
        from the start."""
        return self.lambda_z0 >= self.cap_stretch

    def _outer_gap_mm3(self, lambda_z):
        """The tube's outer volume less the braids' envelope, on the free branch."""
        v_ml = self.tube_state(lambda_z)[0]
        tube = (v_ml + self.V0_ml) * MM3_PER_ML + self.wall_volume_mm3
        return tube - self.braid_volume_mm3(self._angle(lambda_z))

    @cached_property
    def free_end_stretch(self) -> float:
        """Where the free branch ends: first contact, or straight braids, or (straight
        at rest) at once."""
        if self.straight_at_rest:
            return self.lambda_z0
        nearly_straight = self.cap_stretch * (1 - 1e-9)
        if self._outer_gap_mm3(nearly_straight) <= 0:
            return self.cap_stretch
        return brentq(self._outer_gap_mm3, self.lambda_z0, nearly_straight, xtol=1e-14)

    @property
    def meets_straight_braids(self) -> bool:
        """Whether contact happens on the fixed-length branch, at theta = 0."""
        return self.straight_at_rest or self.free_end_stretch == self.cap_stretch

    @property
    def capped_start_hoop(self) -> float:
        """Hoop stretch where the fixed-length branch starts."""
        if self.straight_at_rest:
            return self.cap_stretch**-0.5  # uniaxial tension at p = 0
        return float(np.sqrt(self._hoop_sq(self.free_end_stretch)))

    def _hoop_sq(self, lambda_z):
        return hoop_stretch_sq(lambda_z, self.force_ratio)

    @cached_property
    def contact_angle(self) -> float:
        if not self.meets_straight_braids:
            return float(self._angle(self.free_end_stretch))
        return STRAIGHT_ANGLE

    @cached_property
    def contact_hoop(self) -> float:
        """Hoop stretch at contact on the fixed-length branch: the tube's inner volume
        is the straight braids' envelope less the wall."""
        inner = self.braid_volume_mm3(self.contact_angle) - self.wall_volume_mm3
        return float(np.sqrt(inner / (np.pi * self.radius_mm**2 * self.l_braid_mm)))

    @property
    def contact_ml(self) -> float:
        return float(self.contact_state(self.contact_angle)[0])

    def capped_state(self, stretch_theta):
        """(supplied v_ml, p_kpa, l_mm) of the tube held at L_braid by straight braids."""
        lt = np.asarray(stretch_theta, dtype=float)
        lz = self.cap_stretch
        p_kpa = capped_pressure_ratio(lt, lz) * self.pressure_scale_kpa
        return self.V0_ml * (lt**2 * lz - 1), p_kpa, np.full(lt.shape, self.l_braid_mm)

    def braid_compression_n(self, stretch_theta):
        """Axial force the straight braids carry on the fixed-length branch (negative:
        tension): the wall's axial force less the pressure on the closed ends,
        pi R H mu (2 lz - lt^2/lz - 1/(lt^2 lz^3)). At most F wherever the branch is
        used."""
        lt = np.asarray(stretch_theta, dtype=float)
        lz = self.cap_stretch
        stress = 2 * lz - lt**2 / lz - 1 / (lt**2 * lz**3)
        return np.pi * self.radius_mm * self.thickness_mm * self.shear_modulus_mpa * stress

    @cached_property
    def peak_stretch(self) -> float | None:
        if self.free_end_stretch <= self.lambda_z0:
            return None
        return interior_maximum(
            lambda lz: self.tube_state(lz)[1], self.lambda_z0, self.free_end_stretch
        )

    def peak_knot(self) -> float | None:
        if self.peak_stretch is None:
            return None
        return (self.peak_stretch - self.lambda_z0) / (self.free_end_stretch - self.lambda_z0)

    def _branches(self):
        """The non-empty branches in order, each s in [0, 1] -> (v_ml, p_kpa, l_mm)."""
        branches = []
        if self.free_end_stretch > self.lambda_z0:
            span = self.free_end_stretch - self.lambda_z0
            branches.append(lambda s: self.tube_state(self.lambda_z0 + s * span))
        if self.meets_straight_braids:
            start, end = self.capped_start_hoop, self.contact_hoop
            branches.append(lambda s: self.capped_state(start + s * (end - start)))
        th0, th1 = self.contact_angle, self.end_angle
        branches.append(lambda s: self.contact_state(th0 + s * (th1 - th0)))
        return branches

    def _state(self, t):
        """t in [k, k + 1]: the k-th non-empty branch (``_branches``), continuous at
        the integers."""
        t = np.asarray(t, dtype=float)
        branches = self._branches()
        index = np.clip(np.floor(t), 0, len(branches) - 1)
        values = [branch(np.clip(t - k, 0, 1)) for k, branch in enumerate(branches)]
        return tuple(
            np.select([index == k for k in range(len(branches))], [v[i] for v in values])
            for i in range(3)
        )

    def describe(self) -> str:
        straight = ", meets straight braids" if self.meets_straight_braids else ""
        return (
            f"braided segment from the paper's numbers (R = {self.radius_mm:g} mm, H = "
            f"{self.thickness_mm:g} mm, braids from {self.end_radius_mm:g} mm, mu = "
            f"{self.shear_modulus_mpa:g} MPa): L_braid = {self.l_braid_mm:g} mm, L_tube = "
            f"{self.l_tube_mm:g} mm, F = {self.axial_force_n:.3f} N; contact at "
            f"{self.contact_ml:.3f} mL{straight}"
        )

    def curve(self, name: str | None = None) -> SegmentCurve:
        """The segment's p(v), l(v) from the unpressurised state to P_END_KPA."""
        count = len(self._branches())
        knots = [np.linspace(0, count, count * (_SAMPLES - 1) + 1)]
        if self.peak_knot() is not None:
            knots.append([self.peak_knot()])  # the free branch is the first
        _, v, p, length = tabulate(self._state, np.unique(np.concatenate(knots)))
        v[0], p[0] = 0.0, 0.0  # the unpressurised state, exactly
        label = name or f"B{self.l_braid_mm:g}-T{self.l_tube_mm:g}"
        return SegmentCurve(label, v, p, length, V0_ml=self.V0_ml, source=self.describe())
