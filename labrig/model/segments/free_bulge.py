"""Latex that stiffens, and a bulge that may sit free of the strips (docs/decisions/0012).

Record 0011's held bulge (``held_bulge``) with Gent's latex past the peak, W = -(mu J_m/2)
ln(1 - (I1 - 3)/J_m), J_m = 97.2 (Gent 1996's fit of Treloar's natural rubber data). With
a limiting invariant the free tube under the braids' constant force F has a second rising
branch, so two phases can coexist free of the strips: Maxwell's state, the same pressure
and axial force in both and the energies balanced across the front. In 0011's variables
(a = lambda_theta^2 lambda_z, b = lambda_z, w over mu per reference volume, P = pR/(2 mu H),
f = F/(2 pi R H mu)):

    w_a(u) = w_a(b) = P,  w_b(u) = w_b(b) = f,
    w(b) - w(u) - f (b_b - b_u) - P (a_b - a_u) = 0.

Its root is one state; the share s of bulged tube grows along it at constant pressure
(the plateau), with the strips at the tube's length touching nothing. Contact is a
complementarity: the bulge is free while its outer volume over its span is below the
strips' solid over that span (``elastica.middle_part``), held (0011's equations, contact
pressure >= 0) while it presses on them; 0011's equations at zero contact pressure are
the five above, so the path switches between the two where they meet: free from the
peak if the free bulge fits inside the strips there, held from the touch, free again if
the held contact pressure returns to zero, to the fill.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np
from scipy.optimize import brentq, root

from labrig.model.segments import elastica
from labrig.model.segments.held_bulge import (
    START_SHARE,
    HeldBulge,
    HeldBulgePath,
    HeldBulgeSegment,
)

# Gent (1996), "A new constitutive relation for rubber", Rubber Chem. Technol. 69, 59-61:
# J_m fitted to Treloar's natural rubber data. The record's bracket, 70 and 130, is +-30 %.
GENT_LIMITING_INVARIANT = 97.2
LIMITING_INVARIANT_BRACKET = (70.0, 130.0)
# the free tube's branch is sampled at this many hoop stretches before its turns are refined
_BRANCH_POINTS = 4001
# samples along a free plateau (it is straight in v, p and l)
_PLATEAU_POINTS = 17
# a held point whose contact pressure is below this (units of 2 mu H/R) has left the strips
_LEFT = -1e-9
# the share of a held seed's step from the touch
_SEED_STEP = 1e-3


@dataclass(frozen=True)
class Coexistence:
    """Maxwell's free two-phase state: the unbulged (u) and bulged (b) phases' (a, b)
    and the pressure ratio P = pR/(2 mu H)."""

    a_u: float
    b_u: float
    a_b: float
    b_b: float
    pressure_ratio: float


class FreeOrHeldBulge(HeldBulge):
    """The path of record 0012 for a ``GentBulgeSegment``."""

    def axial_stretch(self, hoop: float) -> float:
        """lambda_z of the free tube under F at hoop stretch ``hoop`` (>= 1): the root of
        dw/db (a = hoop^2 b, b) = f, one root since dw/db rises with b wherever it is
        positive; from the slack limit (negative there) to the lock. NaN past the
        largest hoop stretch at which the latex can carry F before it locks."""
        free = self.limiting_invariant + 3 - hoop**2
        lock = np.sqrt(0.5 * (free + np.sqrt(free**2 - 4 / hoop**2))) * (1 - 1e-12)

        def axial(b):
            return float(self._gradient(hoop**2 * b, b)[1]) - self.f

        if not axial(lock) > 0:
            return np.nan
        return brentq(axial, hoop**-0.5, lock, xtol=1e-15)

    def branch(self, hoop: float):
        """(a, b, P, w - f b) of the free tube under F at hoop stretch ``hoop``."""
        b = self.axial_stretch(hoop)
        a = hoop**2 * b
        return a, b, float(self._gradient(a, b)[0]), float(self._energy(a, b)) - self.f * b

    def coexistence(self) -> Coexistence | None:
        """Maxwell's state of the free Gent tube under F, or None where its pressure does
        not fall and rise again. The branch's turns are located on a grid of hoop
        stretches and the equal-area pressure found by Brent's method."""
        # up to where the lock still leaves a real axial stretch (free^2 >= 4/hoop^2)
        hoops = np.linspace(1.0, np.sqrt(self.limiting_invariant + 1) * 0.999, _BRANCH_POINTS)
        pressure = np.array([self.branch(h)[2] for h in hoops])
        carried = np.isfinite(pressure)
        hoops, pressure = hoops[carried], pressure[carried]  # a prefix: up to the last F
        turns = np.flatnonzero(np.diff(np.sign(np.diff(pressure)))) + 1
        if len(turns) < 2:
            return None
        peak, valley = int(turns[0]), int(turns[1])

        def at(p, lo, hi):
            return brentq(lambda h: self.branch(h)[2] - p, hoops[lo], hoops[hi], xtol=1e-14)

        def area(p):
            unbulged = self.branch(at(p, 0, peak))
            bulged = self.branch(at(p, valley, len(hoops) - 1))
            return bulged[3] - unbulged[3] - p * (bulged[0] - unbulged[0])

        low = max(pressure[valley], pressure[0])
        high = min(pressure[peak], pressure[-1])
        low, high = low * (1 + 1e-12), high * (1 - 1e-12)
        # no equal areas before the latex stops carrying F: no free coexistence
        if not (low < high and area(low) * area(high) < 0):
            return None
        p_m = brentq(area, low, high, xtol=1e-14)
        a_u, b_u, _, _ = self.branch(at(p_m, 0, peak))
        a_b, b_b, _, _ = self.branch(at(p_m, valley, len(hoops) - 1))
        return Coexistence(a_u, b_u, a_b, b_b, p_m)

    def free_length_mm(self, share: float, c: Coexistence) -> float:
        return self.segment.l_tube_mm * ((1 - share) * c.b_u + share * c.b_b)

    def room_mm3(self, share: float, c: Coexistence) -> float:
        """The strips' solid over the free bulge's span less the bulge's outer volume:
        > 0 while the bulge is free inside the strips."""
        seg = self.segment
        length = self.free_length_mm(share, c)
        if length >= seg.l_braid_mm:
            return -np.inf  # the strips straight: no room to bow around a bulge
        span = share * seg.l_tube_mm * c.b_b
        volume = elastica.middle_part(length, span, seg.l_braid_mm, seg.end_radius_mm)[0]
        return volume - share * seg.l_tube_mm * (self.cross_mm2 * c.a_b + self.wall_mm2)

    def free_point(self, share: float, c: Coexistence) -> np.ndarray:
        """(b_u, a_u, theta, s) of the free state at share s (theta from the length)."""
        theta = np.arccos(self.free_length_mm(share, c) / self.segment.l_braid_mm)
        return np.array([c.b_u, c.a_u, theta, share])

    def free_row(self, share: float, c: Coexistence):
        """(v_ml, p_kpa, l_mm, contact_kpa = 0, energy_mj) of the free state at share s."""
        length = self.free_length_mm(share, c)
        phases = (c.a_u, c.b_u), (c.a_b, c.b_b)
        return self.row(share, *phases, length, c.pressure_ratio, 0.0)

    def _touch(self, start: float, c: Coexistence) -> float:
        """The share past ``start`` where the free bulge meets the strips (ValueError if it
        reaches s = 1 free)."""
        shares = np.linspace(start, 1.0, 401)[1:]
        for lo, hi in zip(np.append(start, shares[:-1]), shares, strict=True):
            if self.room_mm3(hi, c) <= 0:
                if not np.isfinite(self.room_mm3(hi, c)):
                    hi = brentq(
                        lambda s: self.free_length_mm(s, c) - self.segment.l_braid_mm, lo, hi
                    )
                    hi -= 1e-12
                return brentq(lambda s: self.room_mm3(s, c), lo, hi, xtol=1e-14)
        raise ValueError("the free bulge reaches s = 1 inside the strips")

    def path(self) -> HeldBulgePath:
        """Free and held pieces from the peak to the fill (module docstring)."""
        c = self.coexistence()
        rows, xs = [], []

        def add_free(first, last):
            for share in np.linspace(first, last, _PLATEAU_POINTS):
                xs.append(self.free_point(share, c))
                rows.append(self.free_row(share, c))

        def leaves(x):
            return self.contact(x[3], x[:3]) < _LEFT

        if c is not None and self.room_mm3(START_SHARE, c) > 0:
            share = START_SHARE
            held = None
        else:
            held = self.start_points()
        while True:
            if held is None:  # free from ``share`` to the touch, then a held seed past it
                touch = self._touch(share, c)
                add_free(share, touch)
                x0 = self.free_point(touch, c)
                seed = touch + _SEED_STEP
                found = root(lambda x, s=seed: self.residual(s, x), x0[:3], tol=1e-13)
                x1 = np.append(found.x, seed)
                if np.max(np.abs(self.residual(seed, found.x))) > 1e-9 or leaves(x1):
                    raise ValueError(f"the bulge touches the strips at s = {touch:.4f} and turns")
                held = [x0, x1]
            points, filled = self.follow(held, leaves)
            # the seed's first point is the free piece's last; a point that left is not kept
            for x in points[1 if xs else 0 : None if filled else -1]:
                xs.append(x)
                rows.append(self.state(x[3], x[:3]))
            if filled:
                break
            if c is None:
                raise ValueError("the held bulge leaves the strips with no free state to take")
            free = self.crossing(points[-2], points[-1], self.contact)
            share, held = float(free[3]), None
        array = np.array(xs)
        columns = [np.array(col, dtype=float) for col in zip(*rows, strict=True)]
        return HeldBulgePath(array[:, 3], array[:, 1], array[:, 0], array[:, 2], *columns)


@dataclass(frozen=True)
class GentBulgeSegment(HeldBulgeSegment):
    """Record 0012's segment: ``HeldBulgeSegment`` with Gent's latex (J_m) past the peak,
    the lobes after the fill included, and the bulge free of the strips where it does not
    press on them. Before the peak, and where there is no bulge, it is record 0008's."""

    limiting_invariant: float | None = GENT_LIMITING_INVARIANT
    path_form: ClassVar[type[HeldBulge]] = FreeOrHeldBulge
    gent_lobes: ClassVar[bool] = True

    def describe(self) -> str:
        text = (
            f"{super().describe()}; Gent's latex past the peak, J_m = {self.limiting_invariant:g}"
        )
        path = self.held_path
        if path is not None and path.contact_kpa[0] == 0.0:
            text += f", the bulge free of the strips at Maxwell's {path.p_kpa[0]:.1f} kPa first"
        return text
