"""Gent's latex and the bulge free of the strips (docs/decisions/0012) against independent
computations: the neo-Hookean limit J_m -> infinity, Maxwell's coexistence against
finite differences of the energy and its equal areas by quadrature along the free tube,
the lobes' Laplace pressure against the energy's derivative, the path's pressure against
the energy's derivative and its quadrature, and the complementarity (free inside the
strips, held pressing on them, the two meeting at zero contact)."""

import numpy as np
import pytest
from scipy.integrate import simpson
from scipy.optimize import root

from labrig.model.segments.free_bulge import FreeOrHeldBulge, GentBulgeSegment
from labrig.model.segments.lobe_branch import LobeBranch
from labrig.model.segments.paper_braided import PaperBraidedSegment

J_M = 97.2


@pytest.fixture(scope="module")
def free():
    segment = GentBulgeSegment(46.0, 20.0)
    bulge = FreeOrHeldBulge(segment, J_M)
    return bulge, bulge.coexistence(), segment.held_path


def _energy_slopes(bulge, a, b, h=1e-6):
    """(dw/da, dw/db) of the Gent energy by central differences of the energy itself."""
    w = bulge._energy
    return (
        float(w(a + h, b) - w(a - h, b)) / (2 * h),
        float(w(a, b + h) - w(a, b - h)) / (2 * h),
    )


def test_coexistence_solves_maxwells_conditions_by_finite_differences(free):
    bulge, c, _ = free
    for a, b in ((c.a_u, c.b_u), (c.a_b, c.b_b)):
        w_a, w_b = _energy_slopes(bulge, a, b)
        assert w_a == pytest.approx(c.pressure_ratio, rel=1e-6)  # the same pressure
        assert w_b == pytest.approx(bulge.f, rel=1e-6)  # the same axial force, F
    jump = float(bulge._energy(c.a_b, c.b_b) - bulge._energy(c.a_u, c.b_u))
    jump -= bulge.f * (c.b_b - c.b_u) + c.pressure_ratio * (c.a_b - c.a_u)
    assert jump == pytest.approx(0.0, abs=1e-8 * bulge._energy(c.a_b, c.b_b))


def test_coexistence_has_equal_areas_by_quadrature(free):
    # along the free tube under F, d(w - f b) = P da: the equal-area rule is the integral
    # of P da from one phase to the other, here by Simpson's rule over the branch (1,001
    # states: about 1e-11 of the area, where 1e-6 is asked)
    bulge, c, _ = free
    hoops = np.linspace(np.sqrt(c.a_u / c.b_u), np.sqrt(c.a_b / c.b_b), 1001)
    branch = np.array([bulge.branch(h)[:3] for h in hoops])
    a, p = branch[:, 0], branch[:, 2]
    area = simpson(p, x=a)
    assert area == pytest.approx(c.pressure_ratio * (c.a_b - c.a_u), rel=1e-6)


def test_neo_hookean_limit():
    segment = PaperBraidedSegment(46.0, 20.0)
    far = FreeOrHeldBulge(segment, 1e12)
    # with S14 alone the free tube under F has no second rising branch: no free bulge
    assert far.coexistence() is None
    plain, limit = (LobeBranch(segment, 0.8, 100.0, j) for j in (None, 1e12))
    env = plain.envelope(0.8)
    for phi in (0.3, 1.0, 2.0):
        assert np.array(limit.terms(env, phi)) == pytest.approx(
            np.array(plain.terms(env, phi)), rel=1e-9
        )


def test_gent_lobes_pressure_is_the_energys_derivative():
    # Laplace's law with Gent's tension against dPi/dphi / dV/dphi at a fixed braid angle
    lobes = LobeBranch(PaperBraidedSegment(46.0, 20.0), 0.8, 100.0, J_M)
    env = lobes.envelope(0.8)
    for phi in (0.5, 1.5, 2.2):
        h = 1e-6
        (v0, e0, _), (v1, e1, _) = (lobes.terms(env, phi + s) for s in (-h, h))
        p_mpa = lobes.terms(env, phi)[2] / 1000
        assert (e1 - e0) / (v1 - v0) == pytest.approx(p_mpa, rel=1e-6)


def test_path_is_free_inside_the_strips_then_presses_on_them(free):
    bulge, c, path = free
    free_part = path.contact_kpa == 0.0
    assert free_part[0] and not free_part[-1]  # B46-T20 starts free and ends held
    touch = int(np.flatnonzero(~free_part)[0]) - 1
    for k in range(touch):
        assert bulge.room_mm3(path.share[k], c) > 0
    assert np.all(path.contact_kpa[touch + 1 :] > 0)
    seg = bulge.segment
    scale = 2 * seg.shear_modulus_mpa * seg.thickness_mm / seg.radius_mm * 1000  # 2 mu H/R
    assert path.p_kpa[: touch + 1] == pytest.approx(c.pressure_ratio * scale, rel=1e-12)
    # at the touch 0011's held equations hold with zero contact pressure
    x = np.array([path.b_u[touch], path.a_u[touch], path.theta[touch]])
    assert np.abs(bulge.residual(path.share[touch], x)) == pytest.approx(np.zeros(3), abs=1e-7)
    assert np.all(np.diff(path.v_ml) > 0)


def test_path_pressure_is_the_energys_derivative_and_its_quadrature(free):
    # a held point (Gent's latex in 0011's equations) and a free one: dE/dv = p, with the
    # held neighbours solved at shares 1e-5 either side
    bulge, c, path = free
    k = len(path.share) - 5
    guess = np.array([path.b_u[k], path.a_u[k], path.theta[k]])
    shares = path.share[k] + np.array([-1e-5, 1e-5])
    held = np.array(
        [
            bulge.state(s, root(lambda y, s=s: bulge.residual(s, y), guess, tol=1e-13).x)
            for s in shares
        ]
    )
    free_rows = np.array([bulge.free_row(s, c) for s in (0.01, 0.02)])
    for rows in (held, free_rows):
        v, p, e = rows[:, 0], rows[:, 1], rows[:, 4]
        assert np.diff(e)[0] / np.diff(v)[0] == pytest.approx(p.mean(), rel=1e-6)
    work = np.sum(np.diff(path.v_ml) * 0.5 * (path.p_kpa[1:] + path.p_kpa[:-1]))
    assert work == pytest.approx(path.energy_mj[-1] - path.energy_mj[0], rel=2e-3)
