"""Stored energy off a p-v curve, against closed forms of piecewise-linear curves."""

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from labrig.analysis.energy import cycle_dE, released_mj, stored_energy_mj


def antiderivative(knots_v, knots_p, x):
    """∫_{v0}^x of the piecewise-linear p by its antiderivative, segment by segment."""
    total = 0.0
    for v0, v1, p0, p1 in zip(knots_v[:-1], knots_v[1:], knots_p[:-1], knots_p[1:], strict=True):
        if x <= v0:
            break
        slope = (p1 - p0) / (v1 - v0) if v1 > v0 else 0.0
        d = min(x, v1) - v0
        total += p0 * d + slope * d * d / 2
    return total


@settings(max_examples=60, deadline=None)
@given(
    steps=st.lists(st.floats(0.01, 5.0), min_size=1, max_size=12),
    pressures=st.lists(st.floats(-20.0, 120.0), min_size=13, max_size=13),
    where=st.floats(0.0, 1.0),
)
def test_the_energy_of_a_piecewise_linear_curve_is_its_closed_form(steps, pressures, where):
    v = np.concatenate([[0.0], np.cumsum(steps)])
    p = np.array(pressures[: len(v)])
    upto = where * v[-1]
    expected = antiderivative(v, p, upto)
    assert stored_energy_mj(v, p, upto) == pytest.approx(expected, rel=1e-9, abs=1e-9)


def snap_cycle():
    """A cycle with one snap each way, in closed form: branch A p = 4 v (kPa, mL), branch
    B p = 2 v - 10; up A to 10 mL, snap to B (40 -> 10 kPa), up B to 20 mL; down B to
    6 mL, snap up to A (2 -> 24 kPa), down A to 0."""
    v_in = np.array([0.0, 10.0, 10.0, 20.0])
    p_in = np.array([0.0, 40.0, 10.0, 30.0])
    v_out = np.array([0.0, 6.0, 6.0, 20.0])  # increasing volume: A below 6 mL, then B
    p_out = np.array([0.0, 24.0, 2.0, 30.0])
    return v_in, p_in, v_out, p_out


def test_a_cycle_dissipates_the_area_between_its_branches():
    # ∫_6^10 (4v - (2v - 10)) dv = [v² + 10 v]_6^10 = 200 - 96 = 104 mJ
    assert released_mj(*snap_cycle()) == pytest.approx(104.0)


def test_the_cycle_dE_of_an_inflation_snap():
    before, returned, dE = cycle_dE(*snap_cycle(), 10.0)
    assert before == pytest.approx(2 * 10.0**2)  # ∫_0^10 4v dv = 200
    # returned from 10 mL: ∫_0^6 4v dv + ∫_6^10 (2v - 10) dv = 72 + 24 = 96
    assert returned == pytest.approx(96.0)
    assert dE == pytest.approx((96.0 - 200.0) / 200.0)


def test_outside_the_curve_there_is_no_energy():
    v_in, p_in, *_ = snap_cycle()
    assert math.isnan(stored_energy_mj(v_in, p_in, 25.0))
    assert math.isnan(stored_energy_mj(v_in[:1], p_in[:1], 0.0))
    assert math.isnan(cycle_dE(*snap_cycle(), 30.0)[2])


def test_nan_points_are_left_out():
    v = np.array([0.0, 1.0, 2.0, 3.0])
    p = np.array([0.0, np.nan, 2.0, 3.0])
    assert stored_energy_mj(v, p, 3.0) == pytest.approx(2.0 / 2 * 2 + 2.5)
