"""Gent spheres against the energy they come from, the neo-Hookean limit, and the
qualitative behaviour of the paper's Fig. S2 (followed here by a two-membrane gradient
flow written for the test, independent of the actuator model)."""

import numpy as np
import pytest
from scipy.optimize import brentq

from labrig.model.segments.gent import (
    GENT_NAMES,
    GentSphere,
    gent_membrane,
    gent_pressure_ratio,
    lock_stretch,
)


def gent_energy_density(stretch, j_m, mu=1.0):
    """S6 at lambda_theta = lambda_phi = lambda."""
    invariant = 2 * stretch**2 + stretch**-4 - 3
    return -mu * j_m / 2 * np.log(1 - invariant / j_m)


@pytest.mark.parametrize("j_m", [20.0, 28.5, 100.0])
def test_s8_is_the_derivative_of_the_gent_energy(j_m):
    # virtual work on the balloon: p dV = dU, U = W 4 pi R^2 H, V = 4/3 pi R^3 lambda^3;
    # with R = H = mu = 1 this is p = W'(lambda) / (4 pi lambda^2) * 4 pi = W'/lambda^2...
    lam = np.linspace(1.01, 0.99 * lock_stretch(j_m), 200)
    h = 1e-6
    d_energy = (gent_energy_density(lam + h, j_m) - gent_energy_density(lam - h, j_m)) / (2 * h)
    d_volume = 4 * np.pi * lam**2  # dV/dlambda with R = 1
    p_ratio = d_energy * 4 * np.pi / d_volume
    np.testing.assert_allclose(gent_pressure_ratio(lam, j_m), p_ratio, rtol=1e-7)


def test_large_j_m_is_the_neo_hookean_balloon():
    lam = np.linspace(1.0, 3.0, 50)
    np.testing.assert_allclose(
        gent_pressure_ratio(lam, 1e9), 2 * (lam**-1 - lam**-7), rtol=1e-7, atol=1e-12
    )


def test_curve_reproduces_the_closed_form_and_has_rise_fall_rise():
    sphere = GentSphere()
    curve = sphere.curve()
    lam = np.random.default_rng(0).uniform(1, sphere.end_stretch, 2000)
    v, p, diameter = sphere.state(lam)
    np.testing.assert_allclose(curve.pressure_kpa(v), p, atol=5e-3, rtol=5e-5)
    np.testing.assert_allclose(curve.length_mm(v), diameter, atol=5e-3)
    assert len(curve.branch_bounds) == 3
    assert curve.peak.v_ml == pytest.approx(sphere.V0_ml * (sphere.extremum_stretches[0] ** 3 - 1))
    assert curve.v_ml[0] == 0.0 and curve.p_kpa[0] == 0.0


def test_peak_moves_to_the_neo_hookean_limit_point_as_j_m_grows():
    # neo-Hookean balloon: d/dlambda (lambda^-1 - lambda^-7) = 0 at lambda = 7^(1/6);
    # stiffening (finite J_m) pushes the peak to larger stretch
    peaks = [GentSphere(j_m=j).extremum_stretches[0] for j in (28.5, 100.0, 1e6)]
    assert peaks[0] > peaks[1] > peaks[2]
    assert peaks[2] == pytest.approx(7 ** (1 / 6), rel=1e-4)


def test_small_j_m_has_no_peak():
    # a Gent balloon loses its limit point for J_m below about 18.2
    curve = GentSphere(j_m=15.0).curve()
    assert curve.peak is None


def inflation_snaps(first, second, v_max_ml, dv_ml, jump_ml):
    """Follow two connected membranes under volume control with the overdamped flow
    dv1/dt = -(p1(v1) - p2(v - v1)): from the previous state the flow runs downhill to
    the nearest root of the pressure difference in its direction. Returns the snaps as
    (total volume, v1 before, v1 after) for jumps larger than jump_ml."""

    def pressure_gap(v1, v):
        return first.pressure_kpa(v1) - second.pressure_kpa(v - v1)

    v1, snaps = 0.0, []
    for v in np.arange(dv_ml, v_max_ml, dv_ml):
        direction = -np.sign(pressure_gap(v1, v))
        limit = v if direction > 0 else 0.0
        new, window = limit, 4 * dv_ml
        while True:  # widen the search window until the flow meets a root or a bound
            end = v1 + direction * window
            end = limit if (end - limit) * direction >= 0 else end
            xs = np.linspace(v1, end, 201)
            gaps = pressure_gap(xs, v)
            crossing = np.flatnonzero(np.sign(gaps[1:]) != np.sign(gaps[0]))
            if len(crossing):
                k = crossing[0]
                new = brentq(pressure_gap, xs[k], xs[k + 1], args=(v,), xtol=1e-12)
                break
            if end == limit:
                break
            window *= 2
        if abs(new - v1) > jump_ml:
            snaps.append((v, v1, new))
        v1 = new
    return snaps


@pytest.fixture(scope="module")
def membranes():
    return {name[-1]: gent_membrane(name) for name in GENT_NAMES}


def run_pair(membranes, pair):
    first, second = membranes[pair[0]], membranes[pair[1]]
    v_a = first.V0_ml
    v_max = 0.95 * (first.v_max_ml + second.v_max_ml)
    return v_a, inflation_snaps(first, second, v_max, 0.02 * v_a, 0.3 * v_a)


def test_fig_s2a_a_and_b_stay_stable(membranes):
    _, snaps = run_pair(membranes, "ab")
    assert snaps == []


def test_fig_s2b_b_and_c_snap_once_into_b(membranes):
    v_a, snaps = run_pair(membranes, "bc")
    assert len(snaps) == 1
    v, before, after = snaps[0]
    assert after > before  # volume flows from c into b
    assert 30 < v / v_a < 50  # the paper's snap is at v / V_a = 42


def test_fig_s2c_a_and_c_snap_twice_and_flow_back(membranes):
    v_a, snaps = run_pair(membranes, "ac")
    assert len(snaps) == 2
    (v_first, a_before, a_after), (v_second, a_again, a_final) = snaps
    assert 15 < v_first / v_a < v_second / v_a < 45
    assert a_after < 0.1 * a_before  # first snap: (almost) all of a's volume goes to c
    assert a_final > a_again  # second snap: some volume flows back into a
