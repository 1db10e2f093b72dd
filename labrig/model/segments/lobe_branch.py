"""The paper-numbers segment past the tube's contact with the braids, with lobes.

Past contact the tube lies on the eight strips and spans the gaps between them as
lobes (``labrig.model.segments.lobes``). The state has two coordinates: the braid angle
theta (the segment's length L_braid cos(theta), and through the elastica the strips'
envelope) and the lobes' half-angle phi. As the contact branch of the SI (S42-S46, in
``BraidedSegment.contact_state``) the tube is its volume-equivalent cylinder: the
envelope's volume V_e(theta) at length l, outer radius r = sqrt(V_e/(pi l)). Then

- enclosed volume V = V_e - (wall) + 8 l a(phi), a the lobe's area beyond the circle;
- hoop stretch lambda_theta = (2 pi r_i + 8 ds(phi))/(2 pi R), r_i the inner radius of
  the equivalent cylinder and ds the lobe's arc beyond the circle's; lambda_z = l/L_tube;
- energy Pi = mu (2 pi R H L_tube) W(lambda_theta, lambda_z) - F l (S14, S31's constant
  braid force; with ``limiting_invariant`` J_m, Gent's W of the same I1, record 0012).

Equilibrium in phi is Laplace's law: dPi/dphi = p dV/dphi gives p = T/rho with T =
mu H W_theta/lambda_z the membrane's hoop tension and rho the lobe's radius (dA/ds =
rho at a fixed chord). Equilibrium in theta, G = dPi/dtheta - p dV/dtheta = 0, is the
strips pushed open; G > 0 holds them where they are (the tube can push the strips out,
not pull them in; where the bulge met them they stay until pushed). So the branch runs
in phi, from the lobes at the start's pressure to P_END_KPA, with theta the start angle
while G(start, phi) >= 0 and G's root otherwise (at most the envelope's largest volume):
the lobes stretch with the strips held until the pressure pushes the strips open, then
both move, the segment shortening.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property
from typing import TYPE_CHECKING

import numpy as np
from scipy.interpolate import CubicSpline
from scipy.optimize import brentq

from labrig.model.segments import lobes
from labrig.model.segments.braided import KPA_PER_MPA, MM3_PER_ML, P_END_KPA
from labrig.model.segments.gent import gent_density
from labrig.model.segments.tabulate import tabulate

if TYPE_CHECKING:
    from labrig.model.segments.paper_braided import PaperBraidedSegment

# the step of the central difference in the braid angle (rad)
ANGLE_STEP = 1e-6
# The envelope's volume is a cubic spline in theta through this many elastica volumes
# (relative error below 1e-10 over the branch's angles); theta from G = 0 in at most
# this many false-position steps over whole arrays, until no step exceeds 1e-10 rad (G's
# central difference carries rounding of about 1e-11 rad in its root).
_ENVELOPE_KNOTS = 801
_ROOT_STEPS = 60
# phi's range: a flat gap membrane at 1e-9, nearly a full circle at 0.99 pi
HALF_ANGLE_LOW = 1e-9
HALF_ANGLE_HIGH = 0.99 * np.pi
_SAMPLES = 17


@dataclass(frozen=True)
class Envelope:
    """What the braid angle fixes: the segment's length, the strips' envelope volume
    (mm^3, at the tube's outer surface) and the equivalent cylinder's outer radius."""

    length_mm: np.ndarray
    volume_mm3: np.ndarray
    radius_mm: np.ndarray


class LobeBranch:
    """The branch of ``segment`` from braid angle ``start_angle`` and pressure
    ``start_kpa`` (module docstring)."""

    def __init__(
        self,
        segment: PaperBraidedSegment,
        start_angle: float,
        start_kpa: float,
        limiting_invariant: float | None = None,
    ):
        self.segment = segment
        # J_m of Gent's latex (docs/decisions/0012); None: S14's neo-Hookean membrane
        self.limiting_invariant = limiting_invariant
        self.start_angle = float(start_angle)
        self.start_kpa = float(start_kpa)
        self.width_mm = lobes.strip_width_mm(segment.end_radius_mm)

    # --- the state at (theta, phi) ----------------------------------------------------
    @cached_property
    def _envelope_volume(self) -> CubicSpline:
        margin = 100 * ANGLE_STEP
        low = max(self.start_angle - margin, 0.0)
        grid = np.linspace(low, self.segment.wall_angle + margin, _ENVELOPE_KNOTS)
        return CubicSpline(grid, self.segment.braid_volume_mm3(grid))

    def envelope(self, theta) -> Envelope:
        th = np.asarray(theta, dtype=float)
        length = self.segment.l_braid_mm * np.cos(th)
        volume = self._envelope_volume(th)
        return Envelope(length, volume, np.sqrt(volume / (np.pi * length)))

    def stretches(self, env: Envelope, phi):
        """(lambda_theta, lambda_z, chord, lobe area beyond the circle) at (env, phi)."""
        seg = self.segment
        r = env.radius_mm
        chord = lobes.chord_mm(r, self.width_mm)
        circle = 0.5 * lobes.gap_angle(r, self.width_mm)
        area = lobes.segment_area_mm2(chord, phi) - lobes.segment_area_mm2(chord, circle)
        extra_arc = lobes.arc_length_mm(chord, phi) - lobes.arc_length_mm(chord, circle)
        inner = np.sqrt((env.volume_mm3 - seg.wall_volume_mm3) / (np.pi * env.length_mm))
        hoop = (2 * np.pi * inner + lobes.STRIP_COUNT * extra_arc) / (2 * np.pi * seg.radius_mm)
        return hoop, env.length_mm / seg.l_tube_mm, chord, area

    def terms(self, env: Envelope, phi):
        """(enclosed volume mm^3, energy mJ, pressure kPa) at (env, phi): the envelope
        less the wall plus the lobes; the membrane's energy (S14 over the undeformed
        wall) less F times the length; Laplace's law p = T/rho with T = mu H
        W_theta/lambda_z (the equilibrium in phi)."""
        seg = self.segment
        hoop, axial, chord, area = self.stretches(env, phi)
        volume = env.volume_mm3 - seg.wall_volume_mm3 + lobes.STRIP_COUNT * env.length_mm * area
        invariant = hoop**2 + axial**2 + 1 / (hoop * axial) ** 2 - 3
        wall_mm3 = 2 * np.pi * seg.radius_mm * seg.thickness_mm * seg.l_tube_mm
        j_m = self.limiting_invariant
        if j_m is None:
            density, stiffening = 0.5 * invariant, 1.0
        else:
            density, stiffening = gent_density(invariant, j_m)
        membrane = seg.shear_modulus_mpa * wall_mm3 * density
        energy = membrane - seg.axial_force_n * env.length_mm
        w_theta = stiffening * (hoop - 1 / (hoop**3 * axial**2))
        tension = seg.shear_modulus_mpa * seg.thickness_mm * w_theta / axial
        pressure = tension / lobes.arc_radius_mm(chord, phi) * KPA_PER_MPA
        return volume, energy, pressure

    def imbalance(self, theta, phi):
        """G = dPi/dtheta - p dV/dtheta at fixed phi (mJ/rad): > 0 holds the strips."""
        v_lo, e_lo, _ = self.terms(self.envelope(theta - ANGLE_STEP), phi)
        v_hi, e_hi, _ = self.terms(self.envelope(theta + ANGLE_STEP), phi)
        p_mpa = self.terms(self.envelope(theta), phi)[2] / KPA_PER_MPA
        # past Gent's lock both energies are infinite: G is undefined (NaN), which
        # ``end_half_angle`` reads as the latex rigid
        with np.errstate(invalid="ignore"):
            return (e_hi - e_lo - p_mpa * (v_hi - v_lo)) / (2 * ANGLE_STEP)

    def state(self, theta, phi):
        """(supplied v_ml, p_kpa, l_mm) at (theta, phi)."""
        env = self.envelope(theta)
        volume, _, pressure = self.terms(env, phi)
        return volume / MM3_PER_ML - self.segment.V0_ml, pressure, env.length_mm

    # --- the branch -------------------------------------------------------------------
    def _half_angle_at(self, theta: float, pressure_kpa: float) -> float:
        env = self.envelope(theta)
        return brentq(
            lambda phi: self.terms(env, phi)[2] - pressure_kpa,
            HALF_ANGLE_LOW,
            HALF_ANGLE_HIGH,
            xtol=1e-14,
        )

    @cached_property
    def start_half_angle(self) -> float:
        """The lobes at the start's pressure: flatter than the circle where the tube
        presses on the strips with less than its own hoop tension needs (the bulge's
        plateau), tighter where more."""
        return self._half_angle_at(self.start_angle, self.start_kpa)

    @cached_property
    def wall_angle(self) -> float:
        """Past the envelope's largest volume the strips cannot open the tube further."""
        return max(self.segment.wall_angle - 100 * ANGLE_STEP, self.start_angle)

    def braid_angle(self, phi):
        """theta at lobe half-angle phi: the start angle while G >= 0 there (the strips
        held), else G's root (G rises with theta; Illinois false position over whole
        arrays), at most the wall's angle."""
        phi = np.asarray(phi, dtype=float)
        low = np.full(phi.shape, self.start_angle)
        high = np.full(phi.shape, self.wall_angle)
        g_low, g_high = self.imbalance(low, phi), self.imbalance(high, phi)
        held, at_wall = g_low >= 0, g_high <= 0
        opening = ~held & ~at_wall
        low, high, g_low, g_high, phi_open = (x[opening] for x in (low, high, g_low, g_high, phi))
        side = np.zeros(low.shape, dtype=int)
        previous = low
        for _ in range(_ROOT_STEPS):
            guess = high - g_high * (high - low) / (g_high - g_low)
            if np.all(np.abs(guess - previous) < 1e-10):
                break
            previous = guess
            g = self.imbalance(guess, phi_open)
            below = g < 0
            # Illinois: halve the stale end's value when the same end moves twice
            g_high = np.where(below & (side == -1), 0.5 * g_high, g_high)
            g_low = np.where(~below & (side == 1), 0.5 * g_low, g_low)
            low, g_low = np.where(below, guess, low), np.where(below, g, g_low)
            high, g_high = np.where(below, high, guess), np.where(below, g_high, g)
            side = np.where(below, -1, 1)
        theta = np.where(held, self.start_angle, self.wall_angle)
        theta[opening] = high - g_high * (high - low) / (g_high - g_low)
        return theta

    def state_along(self, phi):
        """(v_ml, p_kpa, l_mm) at lobe half-angles phi, theta from ``braid_angle``."""
        phi = np.atleast_1d(np.asarray(phi, dtype=float))
        return self.state(self.braid_angle(phi), phi)

    @cached_property
    def end_half_angle(self) -> float:
        """phi where the branch reaches P_END_KPA (past Gent's lock, where the energy is
        infinite and the state undefined, the latex counts as rigid: above it)."""

        def excess_kpa(phi):
            p = float(self.state_along(phi)[1][0])
            return p - P_END_KPA if np.isfinite(p) else P_END_KPA

        return brentq(
            excess_kpa,
            self.start_half_angle,
            HALF_ANGLE_HIGH,
            xtol=1e-13,
        )

    def _evaluate(self, t):
        """t in [0, 1]: phi from the start to the end."""
        phi0 = self.start_half_angle
        return self.state_along(phi0 + np.asarray(t, dtype=float) * (self.end_half_angle - phi0))

    @cached_property
    def table(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(v_ml, p_kpa, l_mm) from the start to P_END_KPA (built once: every curve of
        the segment shares it, read-only)."""
        _, v, p, length = tabulate(self._evaluate, np.linspace(0, 1, _SAMPLES))
        for array in (v, p, length):
            array.setflags(write=False)
        return v, p, length
