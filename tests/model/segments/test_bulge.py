"""The bulging segment: Maxwell's equal-area pressure checked by quadrature of the uniform
curve, the plateau's depth, the half-cosine drop and the plateau as specified, the
two-phase length, and what the bulge does to an actuator (the second segment snaps as it
crosses its peak)."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from support.piecewise_quadrature import integral_of_pressure

from labrig.model.actuator.equilibria import Actuator
from labrig.model.actuator.path import quasi_static_path
from labrig.model.actuator.transitions import transitions
from labrig.model.segments.braid_stiffness import with_braid_stiffness
from labrig.model.segments.bulge import (
    PLATEAU_FALL_KPA,
    bulging_curve,
    maxwell_pressure,
    plateau_pressure,
)
from labrig.model.segments.catalog import analytical_segment

NAMES = ["SI-B46-T20", "SI-B50-T22", "SI-B42-T24"]


@pytest.mark.parametrize("name", NAMES)
def test_maxwells_pressure_is_the_equal_area_pressure(name):
    uniform = analytical_segment(name)
    p_m, v_a, v_b = maxwell_pressure(uniform)
    assert uniform.valley.p_kpa < p_m < uniform.peak.p_kpa
    assert v_a < uniform.peak.v_ml and v_b > uniform.valley.v_ml
    assert uniform.pressure_kpa(v_a) == pytest.approx(p_m, abs=1e-9)
    assert uniform.pressure_kpa(v_b) == pytest.approx(p_m, abs=1e-9)
    # independent of the curve's energy antiderivative: Gauss quadrature of p - p_M
    area = integral_of_pressure(uniform, v_a, v_b) - p_m * (v_b - v_a)
    assert area == pytest.approx(0.0, abs=1e-7 * p_m * (v_b - v_a))


def test_a_gain_of_one_puts_the_plateau_at_maxwells_pressure():
    uniform = analytical_segment("SI-B46-T20")
    p_m, _, _ = maxwell_pressure(uniform)
    assert plateau_pressure(uniform, 1.0) == pytest.approx(p_m, abs=1e-12)
    depth = uniform.peak.p_kpa - p_m
    assert plateau_pressure(uniform, 2.5) == pytest.approx(uniform.peak.p_kpa - 2.5 * depth)


@pytest.mark.parametrize("width", [0.3, 1.5])
def test_drop_plateau_and_the_uniform_curve_around_them(width):
    uniform = analytical_segment("SI-B46-T20")
    bulged = bulging_curve(uniform, 1.0, width)
    p_top = plateau_pressure(uniform, 1.0)
    p_end = p_top - min(PLATEAU_FALL_KPA, uniform.peak.p_kpa - p_top)
    peak = uniform.peak
    assert bulged.peak == peak
    # the plateau ends where the stiffening branch has its end pressure
    v_b = bulged.valley.v_ml
    assert bulged.valley.p_kpa == pytest.approx(p_end)
    assert uniform.pressure_kpa(v_b) == pytest.approx(p_end, abs=1e-9)
    # the uniform samples are kept before the peak and after the plateau
    before = uniform.v_ml[uniform.v_ml <= peak.v_ml]
    after = uniform.v_ml[uniform.v_ml > v_b]
    for v in (before, after):
        np.testing.assert_allclose(bulged.pressure_kpa(v), uniform.pressure_kpa(v), atol=1e-9)
        np.testing.assert_allclose(bulged.length_mm(v), uniform.length_mm(v), atol=1e-9)
    # a half cosine: halfway down at half the width, flat at both ends
    drop_end = peak.v_ml + width
    assert bulged.pressure_kpa(peak.v_ml + width / 2) == pytest.approx(
        0.5 * (peak.p_kpa + p_top), abs=1e-3 * (peak.p_kpa - p_top)
    )
    assert bulged.pressure_kpa(drop_end) == pytest.approx(p_top, abs=1e-9)
    assert abs(bulged.slope_kpa_per_ml(drop_end - 1e-6)) < 0.1 * (peak.p_kpa - p_top) / width
    # on the plateau the tube is two uniform parts: its length the mixture of theirs
    v_a = float(uniform.volume_on_branch(0, p_top)[0])
    l_a, l_b = uniform.length_mm(v_a), uniform.length_mm(v_b)
    v = bulged.v_ml[(bulged.v_ml >= drop_end - 1e-9) & (bulged.v_ml <= v_b)]
    assert len(v) > 10
    mixture = l_a + (v - v_a) / (v_b - v_a) * (l_b - l_a)
    np.testing.assert_allclose(bulged.length_mm(v), mixture, atol=1e-6)
    assert np.all(np.diff(bulged.pressure_kpa(np.linspace(drop_end, v_b, 40))) < 0)


def test_a_plateau_below_the_braids_ends_where_contact_begins():
    uniform = analytical_segment("SI-B46-T20")
    depth = uniform.peak.p_kpa - maxwell_pressure(uniform)[0]
    # deep enough to lie 5 kPa under the valley
    gain = (uniform.peak.p_kpa - uniform.valley.p_kpa + 5.0) / depth
    bulged = bulging_curve(uniform, gain, 1.0)
    assert bulged.valley.v_ml == pytest.approx(uniform.valley.v_ml)
    assert bulged.valley.p_kpa == pytest.approx(plateau_pressure(uniform, gain) - 1.0)
    assert bulged.valley.p_kpa < uniform.valley.p_kpa


def test_bad_constants_and_a_curve_without_a_peak():
    uniform = analytical_segment("SI-B40-T30")
    assert uniform.peak is None
    assert bulging_curve(uniform, 2.0, 1.0) is uniform
    with pytest.raises(ValueError, match="depth_gain"):
        bulging_curve(uniform, 0.0, 1.0)
    with pytest.raises(ValueError, match="drop_width_ml"):
        bulging_curve(uniform, 2.0, -1.0)
    with pytest.raises(ValueError, match="below zero"):
        bulging_curve(analytical_segment("SI-B46-T20"), 1e4, 1.0)


def test_with_a_bulge_the_second_segment_snaps_as_it_crosses_its_peak():
    # uniform SI segments: the second peak crossing is stable (the first segment is on
    # its stiff branch); with a bulge (three times Maxwell's depth, dropping within
    # 0.1 mL) it is where a snap starts
    names = ["SI-B46-T20", "SI-B50-T24"]
    uniform = transitions(quasi_static_path(Actuator([analytical_segment(n) for n in names])))
    bulged = transitions(
        quasi_static_path(Actuator([bulging_curve(analytical_segment(n), 3.0, 0.1) for n in names]))
    )
    second = [t.v_ml for t in uniform if (t.alpha, t.beta) == (1, 2)]
    assert second and not any(not t.stable and abs(t.v_ml - second[0]) < 1e-3 for t in uniform)
    crossing = next(t for t in bulged if (t.alpha, t.beta) == (1, 2))
    snaps_there = [t for t in bulged if not t.stable and abs(t.v_ml - crossing.v_ml) < 1e-2]
    assert snaps_there and snaps_there[0].dE < 0


@settings(max_examples=60, deadline=None)
@given(
    braid=st.sampled_from(range(40, 51, 2)),
    tube=st.sampled_from(range(20, 31, 2)),
    gain=st.floats(0.5, 8.0),
    width=st.floats(0.05, 5.0),
    stiffness=st.floats(20.0, 2000.0),
)
def test_any_bulge_the_fit_may_try_is_a_rise_fall_rise_curve(braid, tube, gain, width, stiffness):
    # the fit's simplex goes anywhere inside its bounds: every curve it builds is a table
    # the actuator model takes (rising volume, one peak, the uniform rise kept before it)
    # or a ValueError, never a malformed curve
    uniform = analytical_segment(f"SI-B{braid}-T{tube}")
    try:
        bulged = with_braid_stiffness(bulging_curve(uniform, gain, width), stiffness)
    except ValueError as exc:
        assert "below zero" in str(exc)
        return
    assert np.all(np.diff(bulged.v_ml) > 0)
    if uniform.peak is None:
        assert bulged is uniform
        return
    assert bulged.peak == uniform.peak
    valley = bulged.valley
    assert valley.v_ml > bulged.peak.v_ml and valley.p_kpa < bulged.peak.p_kpa
    assert valley.p_kpa == pytest.approx(
        plateau_pressure(uniform, gain)
        - min(PLATEAU_FALL_KPA, uniform.peak.p_kpa - plateau_pressure(uniform, gain))
    )
    # after the valley the curve only rises, and no rise is steeper than the braids
    after = bulged.v_ml >= valley.v_ml
    slopes = np.diff(bulged.p_kpa[after]) / np.diff(bulged.v_ml[after])
    assert np.all(slopes > 0) and np.all(slopes <= stiffness * (1 + 1e-9))
