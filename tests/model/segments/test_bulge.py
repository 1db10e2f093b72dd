"""The bulging segment: Maxwell's equal-area plateau checked by quadrature of the uniform
curve, the drop and the plateau as specified, the two-phase length, and what the bulge
does to an actuator (the second segment snaps as it crosses its peak)."""

import numpy as np
import pytest
from scipy.integrate import quad

from labrig.model.actuator.equilibria import Actuator
from labrig.model.actuator.path import quasi_static_path
from labrig.model.actuator.transitions import transitions
from labrig.model.segments.bulge import PLATEAU_FALL, bulging_curve, maxwell_pressure
from labrig.model.segments.catalog import analytical_segment

NAMES = ["SI-B46-T20", "SI-B50-T22", "SI-B42-T24"]


@pytest.mark.parametrize("name", NAMES)
def test_the_plateau_is_maxwells_equal_area_pressure(name):
    uniform = analytical_segment(name)
    p_m, v_a, v_b = maxwell_pressure(uniform)
    assert uniform.valley.p_kpa < p_m < uniform.peak.p_kpa
    assert v_a < uniform.peak.v_ml and v_b > uniform.valley.v_ml
    assert uniform.pressure_kpa(v_a) == pytest.approx(p_m, abs=1e-9)
    assert uniform.pressure_kpa(v_b) == pytest.approx(p_m, abs=1e-9)
    # independent of the curve's energy antiderivative: adaptive quadrature of p - p_M
    breaks = [uniform.peak.v_ml, uniform.valley.v_ml]
    area, _ = quad(
        lambda v: float(uniform.pressure_kpa(v)) - p_m, v_a, v_b, points=breaks, limit=500
    )
    assert area == pytest.approx(0.0, abs=1e-7 * p_m * (v_b - v_a))


@pytest.mark.parametrize("drop", [5.0, 40.0])
def test_drop_plateau_and_the_uniform_curve_around_them(drop):
    uniform = analytical_segment("SI-B46-T20")
    bulged = bulging_curve(uniform, drop)
    p_m, v_a, v_b = maxwell_pressure(uniform)
    assert bulged.peak == uniform.peak
    assert bulged.valley.v_ml == pytest.approx(v_b) and bulged.valley.p_kpa == pytest.approx(p_m)
    # the uniform samples are kept (between the samples around a kink PCHIP's slopes
    # depend on the neighbours, which the bulge changed)
    before = uniform.v_ml[uniform.v_ml <= uniform.peak.v_ml]
    after = np.append(v_b, uniform.v_ml[uniform.v_ml > v_b])
    for v in (before, after):
        np.testing.assert_allclose(bulged.pressure_kpa(v), uniform.pressure_kpa(v), atol=1e-9)
        np.testing.assert_allclose(bulged.length_mm(v), uniform.length_mm(v), atol=1e-9)
    drop_end = uniform.peak.v_ml + (uniform.peak.p_kpa - p_m) * (1 - PLATEAU_FALL) / drop
    middle = 0.5 * (uniform.peak.v_ml + drop_end)
    assert bulged.slope_kpa_per_ml(middle) == pytest.approx(-drop, rel=1e-6)
    # on the plateau the tube is two uniform parts: its length the mixture of theirs
    l_a, l_b = uniform.length_mm(v_a), uniform.length_mm(v_b)
    v = bulged.v_ml[(bulged.v_ml >= drop_end - 1e-9) & (bulged.v_ml <= v_b)]
    assert len(v) > 10
    mixture = l_a + (v - v_a) / (v_b - v_a) * (l_b - l_a)
    np.testing.assert_allclose(bulged.length_mm(v), mixture, atol=1e-6)
    assert np.all(np.diff(bulged.pressure_kpa(np.linspace(drop_end, v_b, 40))) < 0)


def test_a_curve_without_a_peak_is_left_as_it_is():
    uniform = analytical_segment("SI-B40-T30")
    assert uniform.peak is None
    assert bulging_curve(uniform, 10.0) is uniform
    with pytest.raises(ValueError, match="drop_kpa_per_ml"):
        bulging_curve(uniform, 0.0)


def test_with_a_bulge_the_second_segment_snaps_as_it_crosses_its_peak():
    # uniform SI segments: the second peak crossing is stable (the first segment is on
    # its stiff branch); with a steep drop it is where a snap starts
    names = ["SI-B46-T20", "SI-B50-T24"]
    uniform = transitions(quasi_static_path(Actuator([analytical_segment(n) for n in names])))
    bulged = transitions(
        quasi_static_path(Actuator([bulging_curve(analytical_segment(n), 30.0) for n in names]))
    )
    second = [t.v_ml for t in uniform if (t.alpha, t.beta) == (1, 2)]
    assert second and not any(not t.stable and abs(t.v_ml - second[0]) < 1e-3 for t in uniform)
    crossing = next(t for t in bulged if (t.alpha, t.beta) == (1, 2))
    snaps_there = [t for t in bulged if not t.stable and abs(t.v_ml - crossing.v_ml) < 1e-3]
    assert snaps_there and snaps_there[0].dE < 0
