"""The bulge held by the strips (docs/decisions/0011) against independent computations:
the strips' middle part against the elastica integrated as an initial-value problem, the
relaxed membrane energy against its defining minimum and finite differences, the path's
pressure against the energy's derivative and its quadrature, its start against the free
tube under F (S34), and the unilateral contact along it."""

import numpy as np
import pytest
from scipy.integrate import solve_ivp
from scipy.optimize import brentq, minimize_scalar, root
from scipy.special import ellipk

from labrig.model.segments import elastica
from labrig.model.segments.held_bulge import (
    START_SHARE,
    HeldBulge,
    HeldBulgeSegment,
    energy_density,
    energy_gradient,
)
from labrig.model.segments.paper_braided import PaperBraidedSegment

L, A = 46.0, 3.97


def middle_by_integration(length, span):
    """(volume, radius at the part's ends) of the strips' solid between the sections
    ``span`` apart about mid-length, from the elastica theta'' = -lambda^2 sin theta
    integrated from a clamped end with the volume pi r^2 dx alongside."""
    m = float(elastica.modulus_for_shortening(1 - length / L))
    lam = 4 * ellipk(m) / L

    def rhs(_, state):
        theta, kappa, _x, y, _v = state
        cos = np.cos(theta)
        return [kappa, -(lam**2) * np.sin(theta), cos, np.sin(theta), np.pi * (A + y) ** 2 * cos]

    start = [0.0, 2 * np.sqrt(m) * lam, 0.0, 0.0, 0.0]
    sol = solve_ivp(rhs, (0, L / 2), start, rtol=1e-12, atol=1e-12, dense_output=True)
    edge = brentq(lambda s: sol.sol(s)[2] - (length - span) / 2, 0.0, L / 2, xtol=1e-13)
    inner = sol.sol(edge)
    return 2 * (sol.y[4, -1] - inner[4]), A + inner[3]


@pytest.mark.parametrize(("length", "span"), [(40.0, 5.0), (33.0, 12.0), (28.0, 27.9)])
def test_middle_part_against_the_integrated_elastica(length, span):
    volume, front = elastica.middle_part(length, span, L, A)
    expected_volume, expected_front = middle_by_integration(length, span)
    assert volume == pytest.approx(expected_volume, rel=1e-7)
    assert front == pytest.approx(expected_front, rel=1e-7)


def test_middle_part_spans_the_whole_solid_and_its_slope_is_the_section():
    length = 31.0
    whole = float(elastica.envelope_volume_mm3(length, L, A))
    assert elastica.middle_part(length, length, L, A)[0] == pytest.approx(whole, rel=1e-12)
    assert elastica.middle_part(length, 1e-9, L, A)[1] == pytest.approx(
        float(elastica.widest_radius_mm(length, L, A)), rel=1e-9
    )
    h = 1e-4
    low, front = elastica.middle_part(length, 10.0 - h, L, A)[0], None
    high = elastica.middle_part(length, 10.0 + h, L, A)[0]
    front = elastica.middle_part(length, 10.0, L, A)[1]
    assert (high - low) / (2 * h) == pytest.approx(np.pi * front**2, rel=1e-7)


@pytest.mark.parametrize(("a", "b"), [(1.3, 1.5), (2.0, 0.9), (1.3, 0.8), (6.0, 0.5)])
def test_relaxed_energy_is_the_least_over_the_slack_axial_stretch(a, b):
    # at a fixed hoop stretch a membrane that wrinkles axially takes the least energy of
    # the taut membrane over every shorter natural length: min over lambda_z >= b
    hoop = np.sqrt(a / b)

    def taut(lz):
        return 0.5 * (hoop**2 + lz**2 + 1 / (hoop * lz) ** 2 - 3)

    least = minimize_scalar(taut, bounds=(b, 10.0), method="bounded", options={"xatol": 1e-12})
    assert float(energy_density(a, b)) == pytest.approx(min(least.fun, taut(b)), abs=1e-10)
    h = 1e-6
    w_a, w_b = energy_gradient(a, b)
    assert float(w_a) == pytest.approx(
        float(energy_density(a + h, b) - energy_density(a - h, b)) / (2 * h), rel=1e-6
    )
    assert float(w_b) == pytest.approx(
        float(energy_density(a, b + h) - energy_density(a, b - h)) / (2 * h), rel=1e-6, abs=1e-9
    )


@pytest.fixture(scope="module")
def held():
    segment = PaperBraidedSegment(46.0, 20.0)
    bulge = HeldBulge(segment)
    return bulge, bulge.path()


def test_path_pressure_is_the_energys_derivative(held):
    bulge, path = held
    k = len(path.share) // 2
    x = np.array([path.b_u[k], path.a_u[k], path.theta[k]])
    states = []
    for share in (path.share[k] - 1e-5, path.share[k] + 1e-5):
        found = root(lambda y, s=share: bulge.residual(s, y), x, tol=1e-13)
        states.append(bulge.state(share, found.x))
    (v0, p0, *_, e0), (v1, p1, *_, e1) = states
    assert (e1 - e0) / (v1 - v0) == pytest.approx(0.5 * (p0 + p1), rel=1e-6)


def test_path_energy_balance_by_quadrature(held):
    _, path = held
    work = np.sum(np.diff(path.v_ml) * 0.5 * (path.p_kpa[1:] + path.p_kpa[:-1]))
    change = path.energy_mj[-1] - path.energy_mj[0]
    assert work == pytest.approx(change, rel=2e-3)


def test_path_starts_on_the_free_tube_under_the_braid_force(held):
    # as s -> 0 the unbulged phase carries the braids' F alone: it is S34's free tube,
    # whose pressure at its axial stretch S23/S38 give independently. The deviations
    # shrink in proportion to s (2 % at s = 0.002), so they are extrapolated to s = 0
    # from s = 2e-5 and 1e-5 (Richardson, first order).
    bulge, path = held
    assert path.share[0] == START_SHARE
    x = np.array([path.b_u[0], path.a_u[0], path.theta[0]])
    deviations = []
    for share in (1e-3, 3e-4, 1e-4, 3e-5, 2e-5, 1e-5):
        x = root(lambda y, s=share: bulge.residual(s, y), x, tol=1e-14).x
        if share <= 2e-5:
            p_kpa = bulge.state(share, x)[1]
            free_p = float(bulge.segment.tube_state(x[0])[1])
            axial = float(energy_gradient(x[1], x[0])[1])
            deviations.append((axial / bulge.f - 1, p_kpa / free_p - 1))
    at_zero = 2 * np.array(deviations[1]) - np.array(deviations[0])
    assert np.abs(at_zero) == pytest.approx(np.zeros(2), abs=2e-5)


def test_path_presses_on_the_strips_and_ends_filling_them(held):
    bulge, path = held
    assert np.all(path.contact_kpa > 0)
    assert np.all(np.diff(path.v_ml) > 0)
    end = np.array([path.b_u[-1], path.a_u[-1], path.theta[-1]])
    scale = bulge.cross_mm2 * bulge.segment.l_tube_mm
    assert bulge.end_room_mm3(path.share[-1], end) / scale == pytest.approx(0.0, abs=1e-9)


@pytest.mark.parametrize(("braid", "tube"), [(40.0, 30.0), (42.0, 24.0)])
def test_without_a_bulge_to_hold_the_segment_is_0008s(braid, tube):
    # B40-T30 is straight at rest (no peak); B42-T24 fills its strips as it bulges
    held, plain = HeldBulgeSegment(braid, tube).curve(), PaperBraidedSegment(braid, tube).curve()
    assert np.array_equal(held.v_ml, plain.v_ml)
    assert np.array_equal(held.p_kpa, plain.p_kpa)


def test_gent_phases_reduce_to_neo_hookean_and_match_their_derivative():
    # the measuring option of record 0011's Consequences: Gent's latex in the two phases
    segment = PaperBraidedSegment(46.0, 20.0)
    plain, far, gent = (HeldBulge(segment, j) for j in (None, 1e12, 100.0))
    a, b = 30.0, 5.0  # a bulged phase: lambda_theta^2 = 6, lambda_z = 5
    assert far._energy(a, b) == pytest.approx(float(plain._energy(a, b)), rel=1e-9)
    # -(J/2) ln(1 - (I1 - 3)/J) of the first invariant, computed from the stretches
    invariant = a / b + b**2 + 1 / (a * b)
    assert gent._energy(a, b) == pytest.approx(-50 * np.log(1 - (invariant - 3) / 100), rel=1e-12)
    h = 1e-6
    w_a, w_b = gent._gradient(a, b)
    assert w_a == pytest.approx(
        (gent._energy(a + h, b) - gent._energy(a - h, b)) / (2 * h), rel=1e-6
    )
    assert w_b == pytest.approx(
        (gent._energy(a, b + h) - gent._energy(a, b - h)) / (2 * h), rel=1e-6
    )
