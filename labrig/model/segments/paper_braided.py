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

A segment that met straight braids meets them at theta = 0.

Two more things decide when the tube meets the braids (docs/decisions/0007):

- The strips are clamped-clamped elastica (``labrig.model.segments.elastica``), not
  S40's hinged bars: their envelope at length l is the elastica's solid of revolution.
- Past its peak a uniform tube keeps lengthening, straightening the braids until their
  envelope is nearly empty; a latex tube under volume control localises into a bulge
  instead (``Bulge``): the rest of the tube keeps its length, the pressure falls to the
  free tube's Maxwell pressure with the bulged phase at the envelope's widest radius,
  and the bulge spreads along the strips until the tube fills the envelope at the
  peak's length.

Past the fill (or, without a bulge, past first contact) the tube lies on the eight
strips and bulges out between them as lobes (docs/decisions/0008,
``labrig.model.segments.lobe_branch``): the lobes stretch at the strips' length until the
pressure pushes the strips open, then both, the segment shortening, to P_END_KPA.

The same segment with the braid tubing's inner radius read as the paper prints it, a
radius (``BRAID_INNER_RADIUS_AS_PRINTED_MM``, the ``paper-r:`` library,
docs/decisions/0009): the strips' envelope starts at 7.94 mm and the strips are 2 pi
7.94/8 = 6.24 mm wide (``LobeBranch`` takes the width from the end radius). The latex
tube, 3.97 mm outside, then does not touch the braid tubing at rest; both are held by
the end couplings, and nothing else in the form changes.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np
from scipy.optimize import brentq

from labrig.model.segments import elastica
from labrig.model.segments.braided import (
    MM3_PER_ML,
    P_END_KPA,
    BraidedSegment,
    hoop_stretch_sq,
    interior_maximum,
)
from labrig.model.segments.curve import SegmentCurve
from labrig.model.segments.lobe_branch import LobeBranch
from labrig.model.segments.lobes import STRIP_COUNT
from labrig.model.segments.tabulate import tabulate

# Tubing sold by its inner diameter (paper, Materials): the latex tube 1/4" x 1/32", the
# braid tubing 5/16" x 1/16".
TUBE_INNER_RADIUS_MM = 3.175
TUBE_THICKNESS_MM = 0.79
BRAID_INNER_RADIUS_MM = 3.97
# The braid tubing's "inner radius of 7.94 mm" read as printed (docs/decisions/0009).
BRAID_INNER_RADIUS_AS_PRINTED_MM = 7.94
# The first braid angle of the contact branch when the tube meets straight braids: S40
# is 0/0 at theta = 0; 1e-4 rad changes the enclosed volume by about 1e-3 mm^3.
STRAIGHT_ANGLE = 1e-4
_SAMPLES = 33
# The bulge (docs/decisions/0007): the fall from the peak takes this share of the bulged
# volume range (assumed: the bulge meets the strips half-way), the plateau then falls by
# at most PLATEAU_FALL_KPA (a strictly ordered falling branch) until the lobes between
# the strips hold its pressure (docs/decisions/0008).
DROP_SHARE = 0.5
PLATEAU_FALL_KPA = 1.0
# the step of the central difference of the envelope's volume in the braid angle
_ANGLE_STEP = 1e-7


@dataclass(frozen=True)
class Bulge:
    """The two-phase tube past the peak: the plateau (Maxwell's pressure), the unbulged
    phase's axial stretch on the rising branch, the bulged phase's on the falling branch
    (outer radius at the envelope's widest), the braid angle at the peak's length and the
    volume at which the tube fills the envelope there."""

    plateau_kpa: float
    thin_stretch: float
    bulged_stretch: float
    peak_angle: float
    fill_ml: float  # supplied volume at which the tube fills the envelope


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

    def braid_volume_mm3(self, theta):
        """The clamped elastica's envelope at length L_braid cos(theta)
        (``labrig.model.segments.elastica``), not S40's cone."""
        length = self.l_braid_mm * np.cos(np.asarray(theta, dtype=float))
        return elastica.envelope_volume_mm3(length, self.l_braid_mm, self.end_radius_mm)

    def _braid_volume_slope(self, theta):
        h = _ANGLE_STEP
        return (self.braid_volume_mm3(theta + h) - self.braid_volume_mm3(theta - h)) / (2 * h)

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
        """The non-empty branches before contact in order, each s in [0, 1] -> (v_ml,
        p_kpa, l_mm); at least one (the free tube, or the tube held by straight braids)."""
        branches = []
        if self.free_end_stretch > self.lambda_z0:
            span = self.free_end_stretch - self.lambda_z0
            branches.append(lambda s: self.tube_state(self.lambda_z0 + s * span))
        if self.meets_straight_braids:
            start, end = self.capped_start_hoop, self.contact_hoop
            branches.append(lambda s: self.capped_state(start + s * (end - start)))
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

    # --- the bulge past the peak (docs/decisions/0007) --------------------------------
    def free_energy_mj(self, lambda_z):
        """The free tube's potential under F on its uniform branch: the membrane's
        energy (S14 over the undeformed wall 2 pi R H L_tube) less F times its length.
        Its change along the branch is the work int p dv (kPa mL = mJ)."""
        lz = np.asarray(lambda_z, dtype=float)
        lt = np.sqrt(self._hoop_sq(lz))
        wall_mm3 = 2 * np.pi * self.radius_mm * self.thickness_mm * self.l_tube_mm
        membrane = 0.5 * (lt**2 + lz**2 + 1 / (lt * lz) ** 2 - 3)
        work_mj = self.axial_force_n * self.l_tube_mm * lz
        return self.shear_modulus_mpa * wall_mm3 * membrane - work_mj

    def outer_radius_mm(self, lambda_z):
        """The free tube's outer radius on its uniform branch: inner lambda_theta R plus
        the thinned wall H/(lambda_theta lambda_z)."""
        lz = np.asarray(lambda_z, dtype=float)
        lt = np.sqrt(self._hoop_sq(lz))
        return lt * self.radius_mm + self.thickness_mm / (lt * lz)

    def maxwell_pressure_kpa(
        self, bulged_stretch: float, peak_stretch: float | None = None
    ) -> tuple[float, float]:
        """(p_M, thin stretch): the equal-area pressure between the rising branch and the
        bulged phase at axial stretch ``bulged_stretch`` on the falling branch,
        E(b) - E(a) = p_M (v(b) - v(a)), and the unbulged phase's stretch a. The rising
        branch ends at the free tube's peak, ``peak_stretch`` (the segment's own peak if
        not given)."""
        peak_stretch = self.peak_stretch if peak_stretch is None else peak_stretch
        v_b = float(self.tube_state(bulged_stretch)[0])
        e_b = float(self.free_energy_mj(bulged_stretch))

        def thin(p):
            return brentq(lambda lz: self.tube_state(lz)[1] - p, self.lambda_z0, peak_stretch)

        def area(p):
            a = thin(p)
            return e_b - float(self.free_energy_mj(a)) - p * (v_b - float(self.tube_state(a)[0]))

        low = float(self.tube_state(bulged_stretch)[1])
        high = float(self.tube_state(peak_stretch)[1])
        p_m = brentq(area, low, high * (1 - 1e-12), xtol=1e-10)
        return p_m, thin(p_m)

    @cached_property
    def bulge(self) -> Bulge | None:
        """The bulge past the peak, or None where the tube meets the braids uniformly
        (no peak before contact, or an envelope no wider than the tube at its peak)."""
        if self.peak_stretch is None:
            return None
        return self.bulge_at(
            self.peak_stretch * self.l_tube_mm,
            float(self.outer_radius_mm(self.peak_stretch)),
            float(self.tube_state(self.peak_stretch)[0]),
            self.peak_stretch,
        )

    def bulge_at(
        self, peak_length_mm: float, peak_outer_mm: float, peak_ml: float, free_peak: float
    ) -> Bulge | None:
        """The bulge past a peak at length ``peak_length_mm``, where the tube's widest
        outer radius is ``peak_outer_mm`` and its supplied volume ``peak_ml``, with
        Maxwell's construction on the free tube's uniform branch up to its own peak
        ``free_peak`` (axial stretch); None where there is none (``bulge``)."""
        widest = float(
            elastica.widest_radius_mm(peak_length_mm, self.l_braid_mm, self.end_radius_mm)
        )
        if widest <= peak_outer_mm:
            return None
        far = free_peak
        while self.outer_radius_mm(far) < widest:  # the radius grows without bound
            far *= 2
        bulged = brentq(lambda lz: self.outer_radius_mm(lz) - widest, free_peak, far)
        plateau, thin = self.maxwell_pressure_kpa(bulged, free_peak)
        angle = float(np.arccos(min(peak_length_mm / self.l_braid_mm, 1.0)))
        with np.errstate(divide="ignore"):
            fill_ml = float(self.contact_state(min(angle, self.wall_angle))[0])
        if fill_ml <= peak_ml:
            return None
        return Bulge(plateau, thin, bulged, angle, fill_ml)

    @cached_property
    def wall_angle(self) -> float:
        """The braid angle of the envelope's largest volume: past it the strips enclose
        less as they bow further."""
        return brentq(self._braid_volume_slope, STRAIGHT_ANGLE, 0.5 * np.pi - 1e-6)

    @cached_property
    def lobes(self) -> LobeBranch:
        """The branch past the fill (with a bulge: at the plateau's end pressure, at the
        peak's length or the envelope's largest volume) or past first contact."""
        bulge = self.bulge
        if bulge is None:
            before = self._branches()[-1](np.array([1.0]))
            return LobeBranch(self, self.contact_angle, float(before[1][0]))
        return self.lobes_past_fill(bulge, float(self.tube_state(self.peak_stretch)[1]))

    def lobes_past_fill(self, bulge: Bulge, p_peak_kpa: float) -> LobeBranch:
        """The lobes from the fill at the plateau's end pressure (the plateau falls by
        at most PLATEAU_FALL_KPA, and not below the peak less the plateau's depth)."""
        p_end = bulge.plateau_kpa - min(PLATEAU_FALL_KPA, p_peak_kpa - bulge.plateau_kpa)
        return LobeBranch(self, min(bulge.peak_angle, self.wall_angle), p_end)

    def _bulged_tables(self, bulge: Bulge):
        """(v_ml, p_kpa, l_mm) from the unpressurised state through the peak, the fall,
        the plateau and the lobes past the fill."""
        free = np.linspace(self.lambda_z0, self.peak_stretch, _SAMPLES)
        v_a, _, l_a = (float(x) for x in self.tube_state(bulge.thin_stretch))
        return self.bulge_tables(bulge, self.tube_state(free), v_a, l_a)

    def bulge_tables(self, bulge: Bulge, rising, v_a: float, l_a: float, shift_ml: float = 0.0):
        """(v_ml, p_kpa, l_mm): the ``rising`` tables (to the peak, their last state)
        followed by the fall, the plateau and the lobes past the fill. (``v_a``, ``l_a``)
        is the unbulged phase at the plateau's pressure; ``shift_ml`` is added to the
        lobes' supplied volumes (they count from ``V0_ml``), where the rising branch
        counts from another rest volume."""
        v_free, p_free, l_free = (np.asarray(x, dtype=float) for x in rising)
        v_pk, p_pk, l_pk = float(v_free[-1]), float(p_free[-1]), float(l_free[-1])
        v_c, p_c, l_c = self.lobes.table  # starts at the plateau's end pressure
        v_c = v_c + shift_ml
        v_end, l_end = float(v_c[0]), float(l_c[0])

        def mixture_mm(v):  # the bulged phase spans the strips at the length they have
            return l_a + (v - v_a) / (v_end - v_a) * (l_end - l_a)

        drop_end = v_pk + DROP_SHARE * (v_end - v_pk)
        s = np.linspace(0.0, 1.0, _SAMPLES)[1:]
        v_drop = v_pk + s * (drop_end - v_pk)
        p_drop = bulge.plateau_kpa + (p_pk - bulge.plateau_kpa) * 0.5 * (1 + np.cos(np.pi * s))
        l_drop = l_pk + s * (mixture_mm(drop_end) - l_pk)
        v_flat = drop_end + s * (v_end - drop_end)
        p_flat = bulge.plateau_kpa - s * (bulge.plateau_kpa - float(p_c[0]))
        v = np.concatenate([v_free, v_drop, v_flat, v_c[1:]])
        p = np.concatenate([p_free, p_drop, p_flat, p_c[1:]])
        length = np.concatenate([l_free, l_drop, mixture_mm(v_flat), l_c[1:]])
        return v, p, length

    def describe(self) -> str:
        straight = ", meets straight braids" if self.meets_straight_braids else ""
        bulge = self.bulge
        shape = (
            f"bulge plateau {bulge.plateau_kpa:.2f} kPa (free tube's Maxwell pressure), fills "
            f"the braids at {bulge.fill_ml:.3f} mL"
            if bulge
            else f"contact at {self.contact_ml:.3f} mL{straight}"
        )
        shape += f"; lobes between the {STRIP_COUNT} strips to {P_END_KPA:g} kPa"
        return (
            f"braided segment from the paper's numbers (R = {self.radius_mm:g} mm, H = "
            f"{self.thickness_mm:g} mm, elastica braids from {self.end_radius_mm:g} mm, mu = "
            f"{self.shear_modulus_mpa:g} MPa): L_braid = {self.l_braid_mm:g} mm, L_tube = "
            f"{self.l_tube_mm:g} mm, F = {self.axial_force_n:.3f} N; {shape}"
        )

    def curve(self, name: str | None = None) -> SegmentCurve:
        """The segment's p(v), l(v) from the unpressurised state to P_END_KPA."""
        if self.bulge is not None:
            v, p, length = self._bulged_tables(self.bulge)
        else:
            count = len(self._branches())
            knots = [np.linspace(0, count, count * (_SAMPLES - 1) + 1)]
            if self.peak_knot() is not None:
                knots.append([self.peak_knot()])  # the free branch is the first
            _, v, p, length = tabulate(self._state, np.unique(np.concatenate(knots)))
            v_c, p_c, l_c = self.lobes.table  # starts at first contact's state
            v, p = np.concatenate([v, v_c[1:]]), np.concatenate([p, p_c[1:]])
            length = np.concatenate([length, l_c[1:]])
        v[0], p[0] = 0.0, 0.0  # the unpressurised state, exactly
        label = name or f"B{self.l_braid_mm:g}-T{self.l_tube_mm:g}"
        return SegmentCurve(label, v, p, length, V0_ml=self.V0_ml, source=self.describe())
