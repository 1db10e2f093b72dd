"""The braids' spring in series after contact: checked against the series-spring slope,
the work a spring takes, and a wall that becomes a finite slope."""

import numpy as np
import pytest
from support.piecewise_quadrature import integral_of_pressure

from labrig.model.segments.braid_stiffness import with_braid_stiffness
from labrig.model.segments.catalog import analytical_segment
from labrig.model.segments.curve import SegmentCurve

K = 50.0


def test_before_the_valley_nothing_moves():
    curve = analytical_segment("SI-B46-T20")
    stiff = with_braid_stiffness(curve, K)
    before = curve.v_ml <= curve.valley.v_ml
    np.testing.assert_array_equal(stiff.v_ml[before], curve.v_ml[before])
    np.testing.assert_array_equal(stiff.p_kpa, curve.p_kpa)
    np.testing.assert_array_equal(stiff.l_mm, curve.l_mm)
    assert stiff.valley == curve.valley


def test_a_slope_s_becomes_the_series_slope():
    curve = analytical_segment("SI-B46-T20")
    stiff = with_braid_stiffness(curve, K)
    after = np.flatnonzero(curve.v_ml > curve.valley.v_ml)
    i = after[len(after) // 2]
    s = (curve.p_kpa[i + 1] - curve.p_kpa[i]) / (curve.v_ml[i + 1] - curve.v_ml[i])
    s_series = (stiff.p_kpa[i + 1] - stiff.p_kpa[i]) / (stiff.v_ml[i + 1] - stiff.v_ml[i])
    assert s_series == pytest.approx(1 / (1 / s + 1 / K), rel=1e-9)


def test_the_braids_store_the_energy_of_a_spring():
    # the work to reach p on the stiffened curve minus that on the rigid one, each by
    # quadrature of p dv, is the spring's
    curve = analytical_segment("SI-B46-T20")
    stiff = with_braid_stiffness(curve, K)
    i = np.flatnonzero(curve.v_ml > curve.valley.v_ml)[-5]
    p, p_v = curve.p_kpa[i], curve.valley.p_kpa

    # the spring takes dv = dp / K from the valley on: int p dp / K = (p^2 - p_v^2) / 2K
    extra = integral_of_pressure(stiff, 0.0, stiff.v_ml[i]) - integral_of_pressure(
        curve, 0.0, curve.v_ml[i]
    )
    assert extra == pytest.approx((p**2 - p_v**2) / (2 * K), rel=2e-2)


def test_a_wall_becomes_a_finite_slope():
    v = np.array([0.0, 1.0, 2.0, 3.0, 3.0001, 4.0])
    p = np.array([0.0, 60.0, 40.0, 30.0, 300.0, 320.0])
    wall = SegmentCurve("wall", v, p, np.full(6, 100.0), V0_ml=5.0)
    soft = with_braid_stiffness(wall, 200.0)
    slope = (soft.p_kpa[4] - soft.p_kpa[3]) / (soft.v_ml[4] - soft.v_ml[3])
    assert slope < 200.0
    assert slope == pytest.approx(1 / (1e-4 / 270 + 1 / 200), rel=1e-9)


def test_no_valley_no_change_and_a_bad_stiffness():
    curve = analytical_segment("SI-B40-T30")
    assert with_braid_stiffness(curve, K) is curve
    with pytest.raises(ValueError, match="k_kpa_per_ml"):
        with_braid_stiffness(curve, 0.0)
