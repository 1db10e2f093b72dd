"""The lobes of latex between the braid strips against independent computations: the
arc's area and length by quadrature of its Cartesian profile, the shallow-lobe limit
(a parabola's area), the virtual work of the pressure at a fixed chord (dA/ds = rho),
and, on the paper-numbers segment, Laplace's law against the energy's derivative and
the whole branch's work int p dv against its energy (which holds only where both
equilibria, in the lobes and in the strips, are met)."""

import itertools

import numpy as np
import pytest
from scipy.integrate import quad

from labrig.model.segments import lobes
from labrig.model.segments.paper_braided import BRAID_INNER_RADIUS_MM, PaperBraidedSegment

WIDTH = lobes.strip_width_mm(BRAID_INNER_RADIUS_MM)


def test_eight_strips_close_the_tubing_and_open_gaps_as_they_bow():
    # at the tubing's own radius the strips touch; calipers on a strip read the chord
    assert lobes.gap_angle(BRAID_INNER_RADIUS_MM, WIDTH) == 0.0
    assert 2 * BRAID_INNER_RADIUS_MM * np.sin(np.pi / 8) == pytest.approx(3.04, abs=0.005)
    r = 15.0  # the gaps and the strips share the circumference
    covered = lobes.STRIP_COUNT * (WIDTH + r * lobes.gap_angle(r, WIDTH))
    assert covered == pytest.approx(2 * np.pi * r, rel=1e-12)


@pytest.mark.parametrize("half_angle", [0.05, 0.6, 1.4, 2.2])
def test_arc_area_and_length_by_quadrature_of_the_profile(half_angle):
    chord = 7.3
    rho = chord / (2 * np.sin(half_angle))
    base = rho * np.cos(half_angle)  # centre to chord, negative past a semicircle

    def height(x):  # the arc over the chord, y = sqrt(rho^2 - x^2) - base
        return np.sqrt(rho**2 - x**2) - base

    half = chord / 2
    if half_angle <= np.pi / 2:
        area = quad(height, -half, half)[0]
        length = quad(lambda x: rho / np.sqrt(rho**2 - x**2), -half, half)[0]
    else:  # the major arc: the full circle less the minor arc's cap below the chord
        minor = np.pi - half_angle
        cap = rho**2 * (minor - np.sin(minor) * np.cos(minor))
        area = np.pi * rho**2 - cap
        length = 2 * np.pi * rho - 2 * rho * minor
    assert lobes.segment_area_mm2(chord, half_angle) == pytest.approx(area, rel=1e-9)
    assert lobes.arc_length_mm(chord, half_angle) == pytest.approx(length, rel=1e-9)


def test_shallow_lobe_is_a_parabola_beyond_the_circle():
    r, rho = 400.0, 300.0  # both far larger than the chord
    chord = lobes.chord_mm(r, WIDTH * 100)  # a wide gap at a big radius, about 100 mm
    circle = 0.5 * lobes.gap_angle(r, WIDTH * 100)
    phi = np.arcsin(chord / (2 * rho))
    extra = lobes.segment_area_mm2(chord, phi) - lobes.segment_area_mm2(chord, circle)
    assert extra == pytest.approx(chord**3 / 12 * (1 / rho - 1 / r), rel=0.02)


def test_virtual_work_at_a_fixed_chord():
    chord, phi, h = 5.0, 0.9, 1e-6
    d_area = lobes.segment_area_mm2(chord, phi + h) - lobes.segment_area_mm2(chord, phi - h)
    d_arc = lobes.arc_length_mm(chord, phi + h) - lobes.arc_length_mm(chord, phi - h)
    assert d_area / d_arc == pytest.approx(lobes.arc_radius_mm(chord, phi), rel=1e-7)


@pytest.fixture(scope="module", params=[(46, 20), (40, 30)])
def branch(request):
    """A bulged segment (held, then opening) and one that met straight braids."""
    return PaperBraidedSegment(*request.param).lobes


def test_laplace_pressure_is_the_energys_derivative(branch):
    # along the branch past its first quarter (at first contact on straight braids
    # the gaps are still nanometres wide: volume differences there are rounding)
    phis = np.linspace(branch.start_half_angle, branch.end_half_angle, 9)[2:]
    for phi, theta in zip(phis, branch.braid_angle(phis), strict=True):
        env, h = branch.envelope(theta), 1e-6
        v_hi, e_hi, _ = branch.terms(env, phi + h)
        v_lo, e_lo, _ = branch.terms(env, phi - h)
        expected_kpa = (e_hi - e_lo) / (v_hi - v_lo) * 1000
        assert branch.terms(env, phi)[2] == pytest.approx(expected_kpa, rel=1e-6)


def gauss_legendre(f, lo, hi, points=64):
    """int_lo^hi f by Gauss-Legendre, f evaluated on the whole array at once."""
    nodes, weights = np.polynomial.legendre.leggauss(points)
    x = 0.5 * (hi - lo) * nodes + 0.5 * (hi + lo)
    return 0.5 * (hi - lo) * np.sum(weights * f(x))


def test_the_branchs_work_is_its_energy(branch):
    """int p dv along the branch (Gauss-Legendre in phi on each side of where the strips
    start to open, dv/dphi by central differences) equals the energy's change: the
    strips are held (dtheta = 0) or in equilibrium (G = 0) at every point."""
    phi0, phi1 = branch.start_half_angle, branch.end_half_angle
    held = branch.braid_angle(np.linspace(phi0, phi1, 2001)) == branch.start_angle
    opens = np.linspace(phi0, phi1, 2001)[np.argmin(held)] if not held.all() else phi1

    def energy(phi):
        phi = np.atleast_1d(phi)
        return branch.terms(branch.envelope(branch.braid_angle(phi)), phi)[1]

    def p_dv(phi, h=1e-7):
        v_hi, v_lo = branch.state_along(phi + h)[0], branch.state_along(phi - h)[0]
        return branch.state_along(phi)[1] * (v_hi - v_lo) / (2 * h)

    cuts = sorted({phi0, opens, phi1})
    work = sum(gauss_legendre(p_dv, a, b, 200) for a, b in itertools.pairwise(cuts))
    expected = float(energy(phi1)[0] - energy(phi0)[0])
    assert work == pytest.approx(expected, rel=1e-4)
    assert not held[-1]  # both segments open their strips before 300 kPa
