"""The simulated specimen's behaviour against hand computations: the leak's lost share,
the scaled curve, hysteresis, the first cycle, a burst, and air trapped in a water line
(Boyle's law)."""

import numpy as np
import pytest
from scipy.optimize import brentq

from labrig.model.segments.catalog import load_segment
from labrig.model.segments.curve import SegmentCurve
from labrig.sim.dynamic_plant import ATMOSPHERE_KPA, DynamicPlant, Plumbing
from labrig.sim.plant import Plant
from labrig.sim.specimen import LeakyVolume, SpecimenBehaviour, scaled_curve


def pump(legs):
    """The pump's volume at t: (duration s, rate mL/s) legs one after the other."""

    def at(t):
        volume, start = 0.0, 0.0
        for seconds, rate in legs:
            volume += rate * min(max(t - start, 0.0), seconds)
            start += seconds
        return volume

    return at


def test_what_leaks_is_a_share_of_what_was_infused_and_never_comes_back():
    # 10 mL in, 4 out, 2 in: 12 mL infused, 10 % of it lost: 8 - 1.2
    leaky = LeakyVolume(pump([(10, 1.0), (4, -1.0), (2, 1.0)]), 0.1)
    for t in np.arange(0.0, 16.01, 0.01):
        leaky(float(t))
    assert leaky(16.0) == pytest.approx(8.0 - 1.2)
    assert leaky.lost_ml == pytest.approx(1.2)


def test_a_scaled_curve_scales_the_pressure_at_equal_volume_and_the_slow_plant_follows():
    curve = load_segment("B48-T30")
    stiff = scaled_curve(curve, 1.7)
    v = np.linspace(0.5, 20.0, 40)
    np.testing.assert_allclose(stiff.pressure_kpa(v), 1.7 * curve.pressure_kpa(v))
    np.testing.assert_array_equal(stiff.length_mm(v), curve.length_mm(v))
    # one segment filled at 1 mL/min: the sensor reads its curve plus R Q, 0.002 kPa
    plant = Plant([stiff], pump([(1200, 1 / 60)]))
    for t in np.arange(30.0, 1200.0, 30.0):
        expected = 1.7 * curve.pressure_kpa(t / 60)
        assert plant.pressure_kpa_at(float(t)) == pytest.approx(expected, abs=0.01)


def test_hysteresis_and_the_first_cycle_change_the_pressure_as_the_volume_goes():
    behaviour = SpecimenBehaviour(lambda t: 0.0, hysteresis_kpa=4.0, first_cycle_factor=1.5)
    # first inflation to 10 mL: 1.5 times the curve
    for v in np.arange(0.0, 10.01, 0.05):
        p = behaviour.pressure_kpa(float(v), float(v), 20.0)
    assert p == pytest.approx(30.0)
    # withdrawn to 5 mL: the Mullins factor 1 + 0.5 (5/10)^4, less the whole hysteresis
    for v in np.arange(10.0, 4.99, -0.05):
        p = behaviour.pressure_kpa(20.0 - float(v), float(v), 20.0)
    assert p == pytest.approx(20.0 * (1 + 0.5 / 16) - 4.0)
    # infused again by half the turning volume: half the hysteresis left
    for v in np.arange(5.0, 5.251, 0.05):
        p = behaviour.pressure_kpa(40.0 + float(v), float(v), 20.0)
    assert p == pytest.approx(20.0 * (1 + 0.5 * (5.25 / 10) ** 4) - 2.0)
    # at a low pressure the hysteresis is at most half of it: deflation never reads below 0
    low = SpecimenBehaviour(lambda t: 0.0, hysteresis_kpa=4.0)
    for v in (1.0, 0.5, 0.0):
        p = low.pressure_kpa(1.0 - v, v, 2.0)
    assert p == pytest.approx(1.0)


def test_a_burst_opens_the_specimen_at_the_supplied_volume_for_good():
    supplied = pump([(20, 1.0), (10, -1.0)])
    behaviour = SpecimenBehaviour(supplied, burst_at_ml=12.0)
    assert behaviour.pressure_kpa(11.9, 11.9, 30.0) == 30.0
    assert behaviour.pressure_kpa(12.0, 12.0, 30.0) == 0.0
    assert behaviour.burst_s == 12.0
    assert behaviour.pressure_kpa(25.0, 15.0, 30.0) == 0.0  # withdrawn below: still open


def linear_segment(k_kpa_per_ml: float) -> SegmentCurve:
    v = np.linspace(0.0, 60.0, 13)
    return SegmentCurve("linear", v, k_kpa_per_ml * v, np.full_like(v, 30.0), V0_ml=5.0)


def test_air_trapped_in_a_water_line_takes_its_boyle_share_of_the_pump_volume():
    """A linear segment (2 kPa/mL) behind 10 mL of air: at rest after 20 mL, the bubble
    holds 10 P_atm / (P_atm + p) and the segment the rest, so p solves
    p = 2 (20 - 10 (1 - P_atm / (P_atm + p)) - what the line holds)."""
    air_ml, k, displaced = 10.0, 2.0, 20.0
    plumbing = Plumbing(trapped_air_ml=air_ml, line_compliance_ml_per_kpa=0.002)
    plant = DynamicPlant([linear_segment(k)], pump([(20, 1.0)]), plumbing=plumbing)
    plant.advance_to(40.0)
    p = float(plant.pressure_kpa_at(40.0))

    def residual(p):
        bubble_taken = air_ml * (1 - ATMOSPHERE_KPA / (ATMOSPHERE_KPA + p))
        return k * (displaced - bubble_taken - 0.002 * p) - p

    expected = brentq(residual, 0.0, 100.0)
    assert p == pytest.approx(expected, rel=2e-3)
    assert expected < 0.9 * k * displaced  # the air takes a share worth seeing (3 mL)
