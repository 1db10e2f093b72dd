"""SegmentCurve against closed forms: a cubic p(v) whose extrema, energy and slope are
known analytically."""

import numpy as np
import pytest

from labrig.model.segments.curve import SegmentCurve


def cubic(v):
    return 10 * v - 1.2 * v**2 + 0.04 * v**3


def make_curve(n=801):
    v = np.linspace(0.0, 40.0, n)
    return SegmentCurve("cubic", v, cubic(v), 20 + v / 10, V0_ml=5.0)


def test_extrema_match_the_analytic_roots():
    # p'(v) = 10 - 2.4 v + 0.12 v^2 = 0  ->  v = 10 -+ sqrt(100 - 250/3)
    root = np.sqrt(100 - 10 / 0.12)
    curve = make_curve()
    assert curve.peak.v_ml == pytest.approx(10 - root, abs=0.05)
    assert curve.valley.v_ml == pytest.approx(10 + root, abs=0.05)
    assert curve.peak.p_kpa == pytest.approx(cubic(10 - root), abs=1e-3)
    assert len(curve.branch_bounds) == 3


def test_energy_is_the_integral_of_pressure():
    curve = make_curve()
    exact = 5 * 40**2 - 0.4 * 40**3 + 0.01 * 40**4
    assert curve.energy_mj(40.0) == pytest.approx(exact, rel=1e-6)


def test_slope_and_extrapolation_are_continuous():
    curve = make_curve()
    eps = 1e-6
    end = curve.v_max_ml
    assert curve.pressure_kpa(end + eps) == pytest.approx(curve.pressure_kpa(end), abs=1e-3)
    assert curve.slope_kpa_per_ml(30.0) == pytest.approx(10 - 2.4 * 30 + 0.12 * 900, rel=1e-3)
    e_plus = curve.energy_mj(end + 1.0) - curve.energy_mj(end)
    assert e_plus == pytest.approx(curve.p_kpa[-1] + 0.5 * curve.slope_kpa_per_ml(end), rel=1e-6)


def test_monotone_curve_has_no_peak():
    v = np.linspace(0, 10, 50)
    curve = SegmentCurve("rising", v, v**2, np.zeros_like(v), V0_ml=1.0)
    assert curve.peak is None and curve.valley is None
    assert curve.branch_bounds == [(0, 49)]


def test_flat_plateau_counts_as_one_extremum():
    v = np.arange(8.0)
    p = np.array([0, 2, 4, 4, 4, 3, 5, 7.0])
    curve = SegmentCurve("plateau", v, p, np.zeros_like(v), V0_ml=1.0)
    assert curve.peak.v_ml == 4.0
    assert curve.valley.v_ml == 5.0


@pytest.mark.parametrize(
    ("v", "message"),
    [
        (np.array([0, 1, 1, 2, 3.0]), "increase strictly"),
        (np.array([0, 1, np.nan, 2, 3.0]), "NaN"),
        (np.array([0, 1.0]), "at least 4"),
    ],
)
def test_bad_tables_are_refused(v, message):
    with pytest.raises(ValueError, match=message):
        SegmentCurve("bad", v, np.zeros_like(v), np.zeros_like(v), V0_ml=1.0)
