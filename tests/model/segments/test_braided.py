"""The analytical braided segment against independent computations: membrane equilibrium
solved numerically from the Cauchy stresses, the classical uniaxial neo-Hookean law, the
total elastic energy (p must be its derivative everywhere, also after contact), and the
trends the paper states for L_braid and L_tube."""

import numpy as np
import pytest
from scipy.optimize import brentq, fsolve

from labrig.model.segments.braided import (
    BraidedSegment,
    braid_force_n,
    hoop_stretch_sq,
    tube_pressure_ratio,
    unpressurised_stretch,
)

R, H, MU = 6.35, 0.79, 0.49


def total_energy_mj(seg: BraidedSegment, v_ml, l_mm):
    """Neo-Hookean membrane energy of the tube (S14 times the wall volume 2 pi R H L)
    plus the constant-force braids, F (L_braid - l), from the state (v, l) alone."""
    stretch_z = np.asarray(l_mm) / seg.l_tube_mm
    hoop_sq = (np.asarray(v_ml) + seg.V0_ml) * 1000 / (np.pi * R**2 * np.asarray(l_mm))
    invariant = hoop_sq + stretch_z**2 + 1 / (hoop_sq * stretch_z**2) - 3
    tube = 0.5 * MU * invariant * 2 * np.pi * R * H * seg.l_tube_mm
    return tube + seg.axial_force_n * (seg.l_braid_mm - np.asarray(l_mm))


def membrane_equations(unknowns, stretch_z, force_ratio):
    """Hoop and axial equilibrium of the closed-end membrane, from sigma = mu (lambda^2 -
    lambda_r^2) with lambda_r = 1/(lambda_theta lambda_z) and sigma_theta = p r/h,
    sigma_z = p r/(2h) + F/(2 pi r h), in units of mu H / R."""
    hoop, p_ratio = unknowns
    radial = 1 / (hoop * stretch_z)
    r_over_h = hoop / radial  # (r/R)/(h/H)
    return [
        hoop**2 - radial**2 - p_ratio * r_over_h,
        stretch_z**2 - radial**2 - p_ratio * r_over_h / 2 - force_ratio / (2 * hoop * radial),
    ]


@pytest.fixture(scope="module")
def b46_t20():
    return BraidedSegment(46, 20)


def test_free_tube_matches_a_numerical_root_of_the_equilibrium():
    for stretch_z in [1.01, 1.1, 1.18, 1.5, 2.5]:
        hoop, p_ratio = fsolve(membrane_equations, [1.5, 0.5], args=(stretch_z, 0.0), xtol=1e-13)
        assert np.sqrt(hoop_stretch_sq(stretch_z, 0.0)) == pytest.approx(hoop, rel=1e-9)
        assert tube_pressure_ratio(stretch_z, 0.0) == pytest.approx(p_ratio, rel=1e-9)
        # corrected S28: the enclosed volume grows with the axial stretch
        assert hoop**2 * stretch_z == pytest.approx(stretch_z**3 + np.sqrt(stretch_z**6 - 1))


def test_free_tube_peak_is_the_classical_limit_point():
    # independent: maximise pR/(mu H) of the numerically solved membrane over lambda_z
    grid = np.linspace(1.0005, 2.0, 4001)
    p = [fsolve(membrane_equations, [1.5, 0.5], args=(z, 0.0))[1] for z in grid[::40]]
    coarse = grid[::40][int(np.argmax(p))]
    fine = np.linspace(coarse - 0.02, coarse + 0.02, 401)
    p_fine = [fsolve(membrane_equations, [1.5, 0.5], args=(z, 0.0), xtol=1e-13)[1] for z in fine]
    assert np.max(tube_pressure_ratio(grid, 0.0)) == pytest.approx(max(p_fine), rel=1e-6)


@pytest.mark.parametrize("l_braid", [40, 46, 50])
def test_braided_tube_matches_a_numerical_root_of_the_equilibrium(l_braid):
    seg = BraidedSegment(l_braid, 20)
    for stretch_z in seg.lambda_z0 * np.array([1.001, 1.05, 1.2, 1.4]):
        hoop, p_ratio = fsolve(
            membrane_equations, [1.3, 0.5], args=(stretch_z, seg.force_ratio), xtol=1e-13
        )
        assert hoop_stretch_sq(stretch_z, seg.force_ratio) == pytest.approx(hoop**2, rel=1e-8)
        assert tube_pressure_ratio(stretch_z, seg.force_ratio) == pytest.approx(p_ratio, rel=1e-7)


def test_unpressurised_stretch_is_uniaxial_tension():
    # nominal stress of an incompressible neo-Hookean bar: F / (2 pi R H) = mu (l - l^-2)
    for force_n in [0.0, 2.0, braid_force_n(46), braid_force_n(40), 9.81]:
        ratio = force_n / (np.pi * MU * H * R)
        expected = brentq(
            lambda s, f=force_n: MU * (s - s**-2) * 2 * np.pi * R * H - f, 0.5, 3, xtol=1e-15
        )
        stretch = unpressurised_stretch(ratio)
        assert stretch == pytest.approx(expected, rel=1e-13)
        # a closed-end incompressible tube does not lengthen to first order in p, so p grows
        # like the square root of (stretch - lambda_z0): a 1e-16 root error shows as 1e-8
        assert tube_pressure_ratio(stretch, ratio) == pytest.approx(0.0, abs=1e-7)


def test_pressure_is_the_derivative_of_the_elastic_energy_everywhere(b46_t20):
    # before and after contact: integral of p dv equals the change of the total energy
    curve = b46_t20.curve()
    stored = total_energy_mj(b46_t20, curve.v_ml, curve.l_mm) - total_energy_mj(
        b46_t20, 0.0, curve.l_mm[0]
    )
    np.testing.assert_allclose(curve.energy_mj(curve.v_ml), stored, rtol=2e-6, atol=1e-3)


def test_pchip_of_the_table_reproduces_the_closed_form_between_samples(b46_t20):
    curve = b46_t20.curve()
    t = np.random.default_rng(1).uniform(0, 2, 4000)
    v, p, length = b46_t20._state(t)
    np.testing.assert_allclose(curve.pressure_kpa(v), p, atol=5e-3, rtol=5e-5)
    np.testing.assert_allclose(curve.length_mm(v), length, atol=5e-3)


def test_unpressurised_state_and_positive_pressure(b46_t20):
    curve = b46_t20.curve()
    assert curve.v_ml[0] == 0.0 and curve.p_kpa[0] == 0.0
    assert np.all(curve.p_kpa[1:] > 0)
    assert curve.l_mm[0] == pytest.approx(b46_t20.lambda_z0 * 20)
    assert curve.V0_ml == pytest.approx(np.pi * R**2 * 20 / 1000)
    assert curve.p_kpa[-1] == pytest.approx(300, rel=1e-6)


def test_volume_grows_with_the_axial_stretch_before_contact(b46_t20):
    stretch = np.linspace(b46_t20.lambda_z0, b46_t20.contact_stretch, 2000)
    v, _, _ = b46_t20.tube_state(stretch)
    assert np.all(np.diff(v) > 0)


def test_contact_is_continuous_and_the_braids_hold_the_tube_back(b46_t20):
    seg = b46_t20
    _, p_before, l_before = seg.tube_state(seg.contact_stretch)
    _, p_after, l_after = seg.contact_state(seg.contact_angle)
    assert p_after == pytest.approx(p_before, abs=1e-8)
    assert l_after == pytest.approx(l_before, abs=1e-9)
    # after contact the tube would lengthen if it could: the energy at fixed volume falls
    # as l grows, so the contact force is compressive
    theta = np.linspace(seg.contact_angle, seg.end_angle, 50)[1:]
    v, _, length = seg.contact_state(theta)
    dl = 1e-4
    slope = (total_energy_mj(seg, v, length + dl) - total_energy_mj(seg, v, length - dl)) / 2 / dl
    assert np.all(slope < 0)


def test_segment_grows_then_shrinks_after_contact(b46_t20):
    curve = b46_t20.curve()
    top = int(np.argmax(curve.l_mm))
    assert curve.v_ml[top] == pytest.approx(b46_t20.contact_ml, abs=1e-9)
    assert np.all(np.diff(curve.l_mm[: top + 1]) > 0)
    assert np.all(np.diff(curve.l_mm[top:]) < 0)


def test_valley_is_first_contact_and_the_wall_follows(b46_t20):
    curve = b46_t20.curve()
    assert curve.valley.v_ml == pytest.approx(b46_t20.contact_ml, abs=1e-9)
    assert len(curve.branch_bounds) == 3
    assert curve.pressure_kpa(curve.valley.v_ml + 1.5) > 100  # the wall, 1.5 mL on


def test_shorter_braids_lower_the_peak_and_stiffen_earlier():
    segments = [BraidedSegment(lb, 20) for lb in range(40, 51, 2)]
    peaks = [s.curve().peak.p_kpa for s in segments]
    contacts = [s.contact_ml for s in segments]
    assert np.all(np.diff(peaks) > 0)
    assert np.all(np.diff(contacts) > 0)


def test_tube_length_moves_the_softening_not_the_peak():
    curves = [BraidedSegment(46, lt).curve() for lt in range(20, 31, 2)]
    peaks = np.array([c.peak.p_kpa for c in curves])
    valleys = np.array([c.valley.p_kpa for c in curves])
    np.testing.assert_allclose(peaks, peaks[0], rtol=1e-9)
    assert np.all(np.diff(valleys) > 0)  # shorter tubes lower the softening plateau
    # the pressure-stretch law does not involve L_tube, so the peak volume scales with it
    peak_v = np.array([c.peak.v_ml for c in curves])
    np.testing.assert_allclose(peak_v / np.arange(20, 31, 2), peak_v[0] / 20, rtol=1e-6)


@pytest.mark.parametrize(("l_braid", "l_tube"), [(40, 28), (40, 30), (42, 30)])
def test_contact_before_the_peak_leaves_one_rising_branch(l_braid, l_tube):
    seg = BraidedSegment(l_braid, l_tube)
    curve = seg.curve()
    assert seg.peak_stretch is None
    assert curve.peak is None and curve.valley is None
    assert curve.branch_bounds == [(0, len(curve.v_ml) - 1)]
    v = np.linspace(0, curve.v_max_ml + 1, 500)
    assert np.all(np.diff(curve.pressure_kpa(v)) > 0)


def test_braids_shorter_than_the_stretched_tube_are_refused():
    with pytest.raises(ValueError, match="longer"):
        BraidedSegment(20, 20)
