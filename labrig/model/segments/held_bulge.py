"""The bulge held by the strips: a two-phase tube at the strips' length (docs/decisions/0011).

Past its peak the paper-numbers tube (``PaperBraidedSegment``) localises into a bulge.
Record 0007 took the bulge's plateau from the free tube under the braids' constant force
F, whose bulged phase is 2-5 times as long as the tube; this form keeps both phases inside
the strips instead:

- a share s of the tube's reference length is bulged, 1 - s is not; each phase is
  uniform, with a = lambda_theta^2 lambda_z (volume per reference volume pi R^2) and
  b = lambda_z, and the neo-Hookean energy per reference length (S14 over the wall
  2 pi R H) w(a, b) = (a/b + b^2 + 1/(ab) - 3)/2 (relaxed where slack, below);
- the bulged part lies along the middle of the strips (``elastica.middle_part``): over
  an axial span l_b its outer volume is the strips' solid between two sections l_b apart,
  so b_b = l_b/(s L_tube) and a_b = (V_b - wall)/(pi R^2 s L_tube);
- the strips hold the length, l_b + (1 - s) b_u L_tube = L_braid cos(theta), and push
  the ends apart with S31's constant F: Pi = 2 pi R H mu L_tube ((1 - s) w_u + s w_b) -
  F L_braid cos(theta), 0008's contact energy.

At a supplied volume Pi is stationary in (b_u, theta, s), a_u following from the volume.
With Lambda = Pi - p V the conditions, divided by 2 pi R H mu L_tube and with P = dw/da
of the unbulged phase (the pressure, pR/(mu H) = 2 P: S23), are

- b_u: w_b(u) - w_b(b) - (w_a(b) - P) D/(pi R^2) = 0, D = dV_b/dl_b = pi r_front^2 (the
  axial force the same across the bulge's front);
- theta: (w_a(b) - P)(dV_b/dtheta + D dl/dtheta)/(pi R^2) + (w_b(b) - f) dl/dtheta = 0,
  f = F/(2 pi R H mu) (the strips' force balancing the bulged phase at the ends);
- s: w(b) - w(u) + (w_a(b) - P)((D b_u - c)/(pi R^2) - a_b) + w_b(b)(b_u - b_b)
  + P (a_u - a_b) = 0, c = pi((R + H)^2 - R^2) (the front moves where the energies
  balance),

with nothing divided by 1 - s. The path is followed in (b_u, a_u, theta, s) by
pseudo-arclength continuation from a bulge of START_SHARE until the unbulged rest fills
the strips' end parts (the fill: the tube's outer volume is the strips' whole solid, at
the latest at s = 1); from there 0008's cylinder and lobes take over. On the way the
unbulged phase goes slack axially: a membrane wrinkles rather than carry compression, so
``energy_density`` is the relaxed energy of tension-field theory there. P - w_a(b) is
the bulged phase's contact pressure on the strips (in units of 2 mu H/R): it must not go
negative.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property
from typing import ClassVar

import numpy as np
from scipy.optimize import brentq, root

from labrig.model.segments import elastica
from labrig.model.segments.braided import KPA_PER_MPA, hoop_stretch_sq
from labrig.model.segments.gent import gent_density
from labrig.model.segments.lobe_branch import ANGLE_STEP, LobeBranch
from labrig.model.segments.paper_braided import DROP_SHARE, Bulge, PaperBraidedSegment

# The path starts with a bulge of 0.2 % of the tube; its steps in (b_u, a_u, theta, s)
# are at most _STEP long (euclidean), at most _MAX_POINTS of them.
START_SHARE = 0.002
_STEP = 0.02
_MAX_POINTS = 2000
# The strips' axial position grows along them while 2 dn^2 - 1 > 0, k^2 < 1/2: a
# shortening below 2 - 2 E(1/2)/K(1/2) = 0.543, l > 0.457 L_braid (the middle part's span
# is then one-to-one); past the envelope's largest volume the strips' middle still holds more.
_LARGEST_ANGLE = float(np.arccos(1 - 0.54))
# A corrector landing up to _CORNER steps from the last point (at any step size: a
# corner, where the path turns by up to acos(1/_CORNER)) is accepted.
_CORNER = 10.0
# the share stepped across a corner the continuation cannot turn (``_across_corner``)
_CORNER_SHARE = 1e-3
# the residual reported outside the states (``_bulged_inside``): far from any root
_OUTSIDE = 1e6
# the largest residual of an accepted point (the conditions are of order 1)
_TOLERANCE = 1e-9
# the step of the central difference of V_b in the braid angle at a fixed span (rad)
_ANGLE_STEP = 1e-6


def energy_density(a, b):
    """w(a, b) = (a/b + b^2 + 1/(ab) - 3)/2: S14 per reference volume, over mu, relaxed
    where the membrane would be in axial compression (a b^3 < 1, lambda_z below the
    uniaxial lambda_theta^(-1/2)): a membrane wrinkles rather than carry compression
    (tension-field theory), so there it keeps the energy of uniaxial hoop tension,
    (lambda_theta^2 + 2/lambda_theta - 3)/2, whatever lambda_z (continuous with its
    slope at a b^3 = 1)."""
    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    hoop = np.sqrt(a / b)
    taut = 0.5 * (a / b + b**2 + 1 / (a * b) - 3)
    return np.where(a * b**3 >= 1, taut, 0.5 * (hoop**2 + 2 / hoop - 3))


def energy_gradient(a, b):
    """(dw/da, dw/db) of ``energy_density``."""
    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    hoop = np.sqrt(a / b)
    slack = (hoop - hoop**-2) / (2 * hoop * b)  # dw/dlambda_theta * dlambda_theta/da
    taut = a * b**3 >= 1
    w_a = np.where(taut, 0.5 * (1 / b - 1 / (a**2 * b)), slack)
    w_b = np.where(taut, 0.5 * (-a / b**2 + 2 * b - 1 / (a * b**2)), -slack * a / b)
    return w_a, w_b


class NoRoom(ValueError):
    """The tube already fills the strips where the bulge would start: nothing to hold."""


@dataclass(frozen=True)
class HeldBulgePath:
    """The path from s = START_SHARE to the fill: per sample the share s, the unbulged phase
    (a_u, b_u), the braid angle, supplied volume, pressure, length and the bulged phase's
    contact pressure on the strips (kPa, >= 0 where the form holds)."""

    share: np.ndarray
    a_u: np.ndarray
    b_u: np.ndarray
    theta: np.ndarray
    v_ml: np.ndarray
    p_kpa: np.ndarray
    l_mm: np.ndarray
    contact_kpa: np.ndarray
    energy_mj: np.ndarray


class HeldBulge:
    """The two-phase tube of ``segment`` (a ``PaperBraidedSegment`` with a bulge)."""

    def __init__(self, segment: PaperBraidedSegment, limiting_invariant: float | None = None):
        self.segment = segment
        self.limiting_invariant = limiting_invariant
        r, h = segment.radius_mm, segment.thickness_mm
        self.membrane_n = 2 * np.pi * r * h * segment.shear_modulus_mpa  # 2 pi R H mu
        self.f = segment.axial_force_n / self.membrane_n
        self.cross_mm2 = np.pi * r**2
        self.wall_mm2 = np.pi * ((r + h) ** 2 - r**2)

    def _energy(self, a, b):
        """The latex's energy per reference volume over mu: ``energy_density``, or with a
        limiting first invariant J_m Gent's -(J_m/2) ln(1 - (I1 - 3)/J_m) of the same
        (relaxed) I1 - 3 = 2 w (a measuring option of docs/decisions/0011's
        Consequences; the record's form is neo-Hookean)."""
        w = energy_density(a, b)
        if self.limiting_invariant is None:
            return w
        return gent_density(2 * w, self.limiting_invariant)[0]

    def _gradient(self, a, b):
        w_a, w_b = energy_gradient(a, b)
        if self.limiting_invariant is None:
            return w_a, w_b
        stiffening = gent_density(2 * energy_density(a, b), self.limiting_invariant)[1]
        return w_a * stiffening, w_b * stiffening

    def _bulged(self, share: float, b_u: float, theta: float, span_shift: float = 0.0):
        """(a_b, b_b, V_b mm^3, D mm^2, l mm, l_b mm) of the bulged phase."""
        seg = self.segment
        length = seg.l_braid_mm * np.cos(theta)
        span = length - (1 - share) * b_u * seg.l_tube_mm + span_shift
        volume, front = elastica.middle_part(length, span, seg.l_braid_mm, seg.end_radius_mm)
        a_b = (volume - self.wall_mm2 * share * seg.l_tube_mm) / (
            self.cross_mm2 * share * seg.l_tube_mm
        )
        b_b = span / (share * seg.l_tube_mm)
        return a_b, b_b, volume, np.pi * front**2, length, span

    def _bulged_inside(self, share, b_u, a_u, theta):
        """The bulged phase (``_bulged``'s tuple) where (s, b_u, a_u, theta) is a state
        at all, None where not: both phases stretched positively, the strips between
        straight and _LARGEST_ANGLE, the bulge's span inside the strips' length, and with
        Gent's latex both phases short of its lock. One call gives the check and the
        phase, which the residual (the root finder's every evaluation) needs both of."""
        seg = self.segment
        if not np.all(np.isfinite([share, b_u, a_u, theta])):
            return None
        if not (0 < share <= 1 and b_u > 0 and a_u > 0 and 0 < theta < _LARGEST_ANGLE):
            return None
        length = seg.l_braid_mm * np.cos(theta)
        span = length - (1 - share) * b_u * seg.l_tube_mm
        if not 0 < span <= length:
            return None
        bulged = self._bulged(share, b_u, theta)
        if self.limiting_invariant is None:
            return bulged
        a_b, b_b = bulged[:2]
        limit = 0.5 * self.limiting_invariant
        inside = energy_density(a_u, b_u) < limit and a_b > 0 and energy_density(a_b, b_b) < limit
        return bulged if inside else None

    def _volume_slope(self, share, b_u, theta, span):
        """dV_b/dtheta at a fixed span (mm^3/rad)."""
        seg = self.segment
        values = []
        for sign in (-1, 1):
            th = theta + sign * _ANGLE_STEP
            length = seg.l_braid_mm * np.cos(th)
            values.append(elastica.middle_part(length, span, seg.l_braid_mm, seg.end_radius_mm)[0])
        return (values[1] - values[0]) / (2 * _ANGLE_STEP)

    def end_room_mm3(self, share: float, x) -> float:
        """The strips' solid outside the bulge less the unbulged phase's outer volume:
        where it reaches 0 the whole tube fills the strips (the fill)."""
        seg = self.segment
        b_u, a_u, theta = (float(y) for y in x)
        bulged = self._bulged_inside(share, b_u, a_u, theta)
        if bulged is None:
            return np.nan
        _, _, volume, _, length, _ = bulged
        whole = float(elastica.envelope_volume_mm3(length, seg.l_braid_mm, seg.end_radius_mm))
        unbulged = (1 - share) * seg.l_tube_mm * (self.cross_mm2 * a_u + self.wall_mm2)
        return whole - volume - unbulged

    def residual(self, share: float, x) -> np.ndarray:
        """The three equilibrium conditions (module docstring) at (b_u, a_u, theta)."""
        b_u, a_u, theta = (float(y) for y in x)
        bulged = self._bulged_inside(share, b_u, a_u, theta)
        if bulged is None:
            return np.full(3, _OUTSIDE)
        a_b, b_b, _, dv_dl, _, span = bulged
        pu_a, pu_b = self._gradient(a_u, b_u)
        pb_a, pb_b = self._gradient(a_b, b_b)
        dl_dtheta = -self.segment.l_braid_mm * np.sin(theta)
        dv_dtheta = self._volume_slope(share, b_u, theta, span)
        excess = pb_a - pu_a  # w_a(b) - P
        axial = pu_b - pb_b - excess * dv_dl / self.cross_mm2
        strips = excess * (dv_dtheta + dv_dl * dl_dtheta) / self.cross_mm2
        strips = (strips + (pb_b - self.f) * dl_dtheta) / self.segment.l_braid_mm
        front = (
            self._energy(a_b, b_b)
            - self._energy(a_u, b_u)
            + excess * ((dv_dl * b_u - self.wall_mm2) / self.cross_mm2 - a_b)
            + pb_b * (b_u - b_b)
            + pu_a * (a_u - a_b)
        )
        return np.array([axial, strips, front])

    def state(self, share: float, x):
        """(v_ml, p_kpa, l_mm, contact_kpa, energy_mj) at share s and (b_u, a_u, theta)."""
        b_u, a_u, theta = (float(y) for y in x)
        a_b, b_b, _, _, length, _ = self._bulged(share, b_u, theta)
        p_u, p_b = self._gradient(a_u, b_u)[0], self._gradient(a_b, b_b)[0]
        return self.row(share, (a_u, b_u), (a_b, b_b), length, p_u, p_u - p_b)

    def row(self, share: float, unbulged, bulged, length_mm: float, pressure, contact):
        """(v_ml, p_kpa, l_mm, contact_kpa, energy_mj) of the unbulged and bulged phases'
        (a, b) at share s, the tube's length, its pressure and the bulge's contact pressure
        (both in units of 2 mu H/R): the one place the two-phase tube's row is computed,
        held (``state``) or free (``free_bulge``)."""
        seg = self.segment
        (a_u, b_u), (a_b, b_b) = unbulged, bulged
        enclosed = (1 - share) * a_u + share * a_b  # over pi R^2 L_tube
        w = (1 - share) * self._energy(a_u, b_u) + share * self._energy(a_b, b_b)
        energy = self.membrane_n * seg.l_tube_mm * float(w) - seg.axial_force_n * length_mm
        scale = 2 * seg.shear_modulus_mpa * seg.thickness_mm / seg.radius_mm * KPA_PER_MPA
        return seg.V0_ml * (enclosed - 1), pressure * scale, length_mm, contact * scale, energy

    def start_guess(self):
        """(b_u, a_u, theta) near s -> 0: 0007's unbulged phase on the rising branch and
        its bulged phase's axial stretch for the small bulge's span."""
        seg = self.segment
        bulge = seg.bulge
        b_u = bulge.thin_stretch
        a_u = float(hoop_stretch_sq(b_u, seg.force_ratio)) * b_u
        length = (1 - START_SHARE) * b_u * seg.l_tube_mm
        length += START_SHARE * bulge.bulged_stretch * seg.l_tube_mm
        theta = float(np.arccos(min(length / seg.l_braid_mm, 1.0)))
        return np.array([b_u, a_u, theta])

    def contact(self, share: float, x) -> float:
        """P - dw/da of the bulged phase (units of 2 mu H/R): its contact pressure on the
        strips, >= 0 where it presses on them."""
        b_u, a_u, theta = (float(y) for y in x)
        a_b, b_b = self._bulged(share, b_u, theta)[:2]
        return float(self._gradient(a_u, b_u)[0] - self._gradient(a_b, b_b)[0])

    def start_points(self) -> list[np.ndarray]:
        """The path's first two points, (b_u, a_u, theta, s) at s = START_SHARE and 5 %
        further, solved from ``start_guess``."""
        share = START_SHARE * 1.05
        first = root(lambda x: self.residual(START_SHARE, x), self.start_guess(), tol=1e-13)
        second = root(lambda x: self.residual(share, x), first.x, tol=1e-13)
        residuals = (self.residual(START_SHARE, first.x), self.residual(share, second.x))
        if max(np.max(np.abs(r)) for r in residuals) > _TOLERANCE:
            raise ValueError(f"no two-phase equilibrium near s = {START_SHARE}")
        if not self.end_room_mm3(START_SHARE, first.x) > 0:
            raise NoRoom("the tube fills the strips as the bulge starts")
        return [np.append(first.x, START_SHARE), np.append(second.x, share)]

    def follow(self, points: list[np.ndarray], leaves=None) -> tuple[list[np.ndarray], bool]:
        """Continue the held path from its last two ``points`` by pseudo-arclength
        continuation in (b_u, a_u, theta, s) (the share need not grow monotonically)
        until the whole tube fills the strips (``end_room_mm3`` = 0, at the latest at
        s = 1; the last point is then the fill: returns (points, True)) or ``leaves``
        (a function of a point) turns true (returns (points, False) with that point
        last). Raises ValueError where the path cannot be followed."""
        points = list(points)
        step = _STEP
        while not self.end_room_mm3(points[-1][3], points[-1][:3]) <= 0:
            if len(points) > _MAX_POINTS:
                raise ValueError(f"the two-phase path stops at s = {points[-1][3]:.4f}")
            if step < _STEP * 1e-4:
                points.append(self._across_corner(points))
                if leaves is not None and leaves(points[-1]):
                    return points, False
                step = _STEP
                continue
            tangent = points[-1] - points[-2]
            tangent /= np.linalg.norm(tangent)
            predicted = points[-1] + step * tangent

            def conditions(x, predicted=predicted, tangent=tangent):
                return np.append(self.residual(x[3], x[:3]), tangent @ (x - predicted))

            found = root(conditions, predicted, tol=1e-13)
            # judged by the residual (hybr's own flag also fails where 1e-13 in x is
            # below what rounding lets it reach); a corrector that lands up to _CORNER steps
            # away is a corner of the path (the unbulged phase going slack, where the
            # relaxed energy is only once differentiable), farther is another branch
            moved = np.linalg.norm(found.x - points[-1])
            if np.max(np.abs(conditions(found.x))) > _TOLERANCE or moved > _CORNER * step:
                step *= 0.5
                continue
            points.append(found.x)
            if leaves is not None and leaves(found.x):
                return points, False
            step = min(step * 1.3, _STEP)
        points[-1] = self.crossing(points[-2], points[-1], self.end_room_mm3)
        return points, True

    def _across_corner(self, points: list[np.ndarray]) -> np.ndarray:
        """The next point past a corner the continuation cannot turn (its tangent jumps
        where the unbulged phase goes slack and Gent's latex steepens the turn): the
        root at a share _CORNER_SHARE further on, from the last point."""
        last = points[-1]
        share = last[3] + np.sign(last[3] - points[-2][3]) * _CORNER_SHARE
        found = root(lambda x: self.residual(share, x), last[:3], tol=1e-13)
        if np.max(np.abs(self.residual(share, found.x))) > _TOLERANCE:
            raise ValueError(f"the two-phase path stops at s = {last[3]:.4f}")
        return np.append(found.x, share)

    def path(self) -> HeldBulgePath:
        """The held path from s = START_SHARE to the fill (``follow``)."""
        points, _ = self.follow(self.start_points())
        xs = np.array(points)
        rows = [self.state(x[3], x[:3]) for x in xs]
        columns = [np.array(col, dtype=float) for col in zip(*rows, strict=True)]
        return HeldBulgePath(xs[:, 3], xs[:, 1], xs[:, 0], xs[:, 2], *columns)

    def crossing(self, before, after, measure) -> np.ndarray:
        """The point between two path points where ``measure(share, x)`` crosses 0 (the
        fill with ``end_room_mm3``): on the hyperplanes across the chord from ``before``
        to ``after`` (as the continuation's), by Brent's method in the chord's fraction."""
        chord = after - before

        def on_path(fraction):
            predicted = before + fraction * chord

            def conditions(x):
                return np.append(self.residual(x[3], x[:3]), chord @ (x - predicted))

            return root(conditions, predicted, tol=1e-13).x

        def value(fraction):
            x = on_path(fraction)
            return measure(x[3], x[:3])

        fraction = brentq(value, 0.0, 1.0, xtol=1e-12)
        found = on_path(fraction)
        if np.max(np.abs(self.residual(found[3], found[:3]))) > _TOLERANCE:
            raise ValueError("the two-phase path's crossing was not found")
        return found


class _StripsFrom:
    """The segment as ``LobeBranch`` sees it from a fill past the envelope's largest
    volume: its wall angle just past the fill's angle (the strips' whole solid holds
    less as they bow further, so they stay where the path left them)."""

    def __init__(self, segment: PaperBraidedSegment, angle: float):
        self._segment = segment
        self.wall_angle = max(segment.wall_angle, angle + 300 * ANGLE_STEP)

    def __getattr__(self, name):
        return getattr(self._segment, name)


@dataclass(frozen=True)
class HeldBulgeSegment(PaperBraidedSegment):
    """``PaperBraidedSegment`` with the bulge held by the strips past the peak
    (docs/decisions/0011): the fall from the peak onto the two-phase path (0007's half
    cosine over DROP_SHARE of the volume to the fill), the path to the fill, then 0008's
    lobes from the path's angle and pressure. Where 0007 has no bulge, or the tube
    already fills the strips where the bulge would start, it is 0008's segment.
    ``limiting_invariant`` (J_m) makes the two phases Gent's latex instead of the
    neo-Hookean one (a measuring option; everything before the peak and the lobes stay
    neo-Hookean)."""

    limiting_invariant: float | None = None
    # the path's form, and whether the lobes after the fill share the phases' latex
    # (record 0011's measuring option keeps them neo-Hookean; record 0012 does not)
    path_form: ClassVar[type[HeldBulge]] = HeldBulge
    gent_lobes: ClassVar[bool] = False

    @cached_property
    def held_path(self) -> HeldBulgePath | None:
        if self.bulge is None:
            return None
        try:
            return self.path_form(self, self.limiting_invariant).path()
        except NoRoom:
            return None

    @cached_property
    def lobes(self) -> LobeBranch:
        path = self.held_path
        if path is None:
            return PaperBraidedSegment.lobes.func(self)
        angle = float(path.theta[-1])
        latex = self.limiting_invariant if self.gent_lobes else None
        return LobeBranch(_StripsFrom(self, angle), angle, float(path.p_kpa[-1]), latex)

    def _bulged_tables(self, bulge: Bulge):
        path = self.held_path
        if path is None:
            return super()._bulged_tables(bulge)
        free = np.linspace(self.lambda_z0, self.peak_stretch, 33)
        v_free, p_free, l_free = self.tube_state(free)
        v_pk, p_pk, l_pk = float(v_free[-1]), float(p_free[-1]), float(l_free[-1])
        v_c, p_c, l_c = self.lobes.table
        # the path up to where the lobes take over (their start may lie a little below
        # the fill's volume, where the cylinder's flat lobes hold less than the phases)
        keep = (path.v_ml > v_pk) & (path.v_ml < v_c[0])
        v_path, p_path, l_path = path.v_ml[keep], path.p_kpa[keep], path.l_mm[keep]
        width = DROP_SHARE * (v_c[0] - v_pk)
        p_gap = p_pk - float(np.interp(v_pk, path.v_ml, path.p_kpa))
        l_gap = l_pk - float(np.interp(v_pk, path.v_ml, path.l_mm))
        v_drop = v_pk + width * np.linspace(0.0, 1.0, 33)[1:]
        blend = 0.5 * (1 + np.cos(np.pi * (v_drop - v_pk) / width))
        p_drop = np.interp(v_drop, path.v_ml, path.p_kpa) + p_gap * blend
        l_drop = np.interp(v_drop, path.v_ml, path.l_mm) + l_gap * blend
        after = v_path > v_drop[-1]  # the drop ends half-way to the lobes' start
        v = np.concatenate([v_free, v_drop, v_path[after], v_c])
        p = np.concatenate([p_free, p_drop, p_path[after], p_c])
        length = np.concatenate([l_free, l_drop, l_path[after], l_c])
        return v, p, length

    def describe(self) -> str:
        path = self.held_path
        if path is None:
            return super().describe()
        return (
            f"{super().describe()}; the bulge held by the strips (a two-phase tube at the "
            f"strips' length), filling them at {path.v_ml[-1]:.3f} mL, {path.p_kpa[-1]:.1f} kPa"
        )
