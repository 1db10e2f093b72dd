"""The Ogden braided segment (the calibrated library's form) against independent
computations: the SI's closed forms at alpha = 2, the energy's derivatives by finite
differences, p = dPi/dv along the whole table, and what alpha and the contact
compliance change."""

import numpy as np
import pytest

from labrig.model.segments.braided import BraidedSegment
from labrig.model.segments.ogden_braided import (
    OgdenBraidedSegment,
    axial_stretch,
    ogden_energy,
    ogden_gradient,
)


def neo_hookean_energy(stretch_theta, stretch_z):
    """S14 / mu with lambda_r = 1/(lambda_theta lambda_z)."""
    return 0.5 * (stretch_theta**2 + stretch_z**2 + (stretch_theta * stretch_z) ** -2 - 3)


def total_energy_mj(seg: OgdenBraidedSegment, v_ml, l_mm):
    """Ogden energy of the wall (W times 2 pi R H L_tube) plus the braids, F (L_braid -
    l), from the state (v, l) alone: lambda_z = l / L_tube, lambda_theta^2 = V /
    (pi R^2 l)."""
    r = seg.radius_mm
    stretch_z = np.asarray(l_mm) / seg.l_tube_mm
    hoop = np.sqrt((np.asarray(v_ml) + seg.V0_ml) * 1000 / (np.pi * r**2 * np.asarray(l_mm)))
    wall_mm3 = 2 * np.pi * r * seg.thickness_mm * seg.l_tube_mm
    tube = seg.shear_modulus_mpa * wall_mm3 * ogden_energy(hoop, stretch_z, seg.ogden_alpha)
    return tube + seg.axial_force_n * (seg.l_braid_mm - np.asarray(l_mm))


def test_alpha_two_is_the_neo_hookean_energy():
    lt, lz = np.meshgrid(np.linspace(0.8, 3.0, 7), np.linspace(0.9, 2.0, 5))
    assert np.allclose(ogden_energy(lt, lz, 2.0), neo_hookean_energy(lt, lz), rtol=1e-13)


@pytest.mark.parametrize("alpha", [1.0, 1.4, 2.0])
def test_gradient_is_the_energy_derivative(alpha):
    lt, lz = np.meshgrid(np.linspace(0.9, 3.0, 6), np.linspace(0.95, 1.8, 4))
    h = 1e-6
    d_theta = (ogden_energy(lt + h, lz, alpha) - ogden_energy(lt - h, lz, alpha)) / (2 * h)
    d_z = (ogden_energy(lt, lz + h, alpha) - ogden_energy(lt, lz - h, alpha)) / (2 * h)
    w_theta, w_z = ogden_gradient(lt, lz, alpha)
    assert np.allclose(w_theta, d_theta, rtol=1e-7, atol=1e-9)
    assert np.allclose(w_z, d_z, rtol=1e-7, atol=1e-9)


def test_alpha_two_reproduces_the_si_closed_forms():
    # the SI's S35-S39 (closed forms in lambda_z) against the numerical axial root in
    # lambda_theta: the same peak, valley, contact and unpressurised stretch
    for braid, tube in [(46, 20), (40, 26), (50, 30)]:
        si = BraidedSegment(braid, tube)
        ogden = OgdenBraidedSegment(braid, tube, ogden_alpha=2.0)
        assert ogden.lambda_z0 == pytest.approx(si.lambda_z0, rel=1e-12)
        assert ogden.contact_ml == pytest.approx(si.contact_ml, rel=1e-9)
        a, b = si.curve(), ogden.curve()
        assert b.peak.p_kpa == pytest.approx(a.peak.p_kpa, rel=1e-9)
        assert b.peak.v_ml == pytest.approx(a.peak.v_ml, rel=1e-6)
        assert b.valley.p_kpa == pytest.approx(a.valley.p_kpa, rel=1e-9)
        v = np.linspace(0.01, 0.97 * a.v_max_ml, 300)
        assert np.allclose(b.pressure_kpa(v), a.pressure_kpa(v), rtol=1e-4, atol=2e-3)


@pytest.mark.parametrize("alpha", [1.2, 1.6])
def test_axial_stretch_solves_the_axial_equilibrium(alpha):
    # independent: the axial force balance from the Cauchy stresses of the membrane,
    # sigma_z h 2 pi r = p pi r^2 + F with sigma_i = lambda_i dW/dlambda_i - sigma_r-part
    # folded in (plane stress), p from the hoop balance sigma_theta = p r / h
    force_stress = 0.4
    lt = np.linspace(1.05, 2.5, 9)
    lz = axial_stretch(lt, alpha, force_stress)
    w_theta, w_z = ogden_gradient(lt, lz, alpha)
    sigma_theta, sigma_z = lt * w_theta, lz * w_z  # Cauchy stresses over mu (lambda_r W_r = 0)
    h_over_r = 1 / (lt**2 * lz)  # (h/H)/(r/R) in units of H/R
    p = sigma_theta * h_over_r  # p R / (mu H)
    axial = sigma_z * 2 * h_over_r - p - 2 * force_stress / (lt**2)  # both sides / (pi r^2)
    assert np.allclose(axial, 0.0, atol=1e-10)


@pytest.mark.parametrize("alpha", [1.3, 1.7])
def test_pressure_is_the_derivative_of_the_total_energy(alpha):
    seg = OgdenBraidedSegment(46, 22, shear_modulus_mpa=0.7, ogden_alpha=alpha)
    curve = seg.curve()
    t = np.concatenate([np.linspace(0.05, 0.95, 19), np.linspace(1.05, 1.9, 12)])
    h = 1e-6
    v_lo, _, l_lo = seg._state(t - h)
    v_hi, _, l_hi = seg._state(t + h)
    _, p, _ = seg._state(t)
    dpi = total_energy_mj(seg, v_hi, l_hi) - total_energy_mj(seg, v_lo, l_lo)
    assert np.allclose(dpi / (v_hi - v_lo), p, rtol=1e-5)
    # and the table's own energy is its integral
    assert curve.peak is not None and curve.valley.v_ml == pytest.approx(seg.contact_ml)


def test_lower_alpha_softens_more_after_the_peak():
    dips = []
    for alpha in (2.0, 1.5, 1.0):
        curve = OgdenBraidedSegment(50, 20, envelope_radius_mm=7.94, ogden_alpha=alpha).curve()
        dips.append(1 - curve.valley.p_kpa / curve.peak.p_kpa)
    assert dips[0] < dips[1] < dips[2]


def test_contact_compliance_spreads_the_stiffening_and_keeps_pressure_and_length():
    rigid = OgdenBraidedSegment(46, 20, ogden_alpha=1.5)
    compliant = OgdenBraidedSegment(46, 20, ogden_alpha=1.5, contact_compliance=3.0)
    a, b = rigid.curve(), compliant.curve()
    assert b.valley.p_kpa == pytest.approx(a.valley.p_kpa, rel=1e-12)
    assert b.valley.v_ml == pytest.approx(a.valley.v_ml, rel=1e-12)
    t = np.linspace(1.1, 1.9, 9)
    va, pa, la = rigid._state(t)
    vb, pb, lb = compliant._state(t)
    assert np.allclose(pb, pa) and np.allclose(lb, la)
    assert np.allclose(vb - rigid.contact_ml, 3.0 * (va - rigid.contact_ml))
    # p(v) stays continuous through contact
    v_c = rigid.contact_ml
    assert b.pressure_kpa(v_c + 1e-7) == pytest.approx(b.pressure_kpa(v_c - 1e-7), abs=1e-4)


def test_bad_constants_are_refused():
    with pytest.raises(ValueError, match="ogden_alpha"):
        OgdenBraidedSegment(46, 20, ogden_alpha=0.5)
    with pytest.raises(ValueError, match="contact_compliance"):
        OgdenBraidedSegment(46, 20, contact_compliance=0.5)
