"""MPX5100 conversion, range flags and zeroing, against the datasheet's own numbers."""

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from labrig.drivers import mpx5100
from labrig.errors import DeviceError


def test_datasheet_points_at_5_v():
    # Datasheet: 0.2 V at 0 kPa, 4.7 V at 100 kPa, 45 mV/kPa with a 5.0 V supply.
    assert mpx5100.pressure_kpa(0.2) == pytest.approx(0.0, abs=1e-12)
    assert mpx5100.pressure_kpa(4.7) == pytest.approx(100.0)
    assert mpx5100.pressure_kpa(0.2 + 0.045) == pytest.approx(1.0)
    assert mpx5100.output_v(100.0) == pytest.approx(4.7)


def test_conversion_is_ratiometric():
    # At 4.8 V the same pressure gives 4.8/5 of the voltage; assuming 5 V would be wrong.
    v = 4.7 * 4.8 / 5.0
    assert mpx5100.pressure_kpa(v, 4.8) == pytest.approx(100.0)
    assert mpx5100.pressure_kpa(v, 5.0) == pytest.approx((v / 5.0 - 0.04) / 0.009)
    assert mpx5100.pressure_kpa(v, 5.0) < 96.0


@given(
    st.floats(-20.0, 130.0, allow_nan=False),
    st.floats(4.5, 5.5, allow_nan=False),
)
def test_output_and_pressure_are_inverses(p_kpa, v_supply):
    v = mpx5100.output_v(p_kpa, v_supply)
    assert mpx5100.pressure_kpa(v, v_supply) == pytest.approx(p_kpa, abs=1e-9)


def test_conversion_takes_arrays_and_a_measured_supply_per_sample():
    v_supply = np.array([4.9, 5.0, 5.1])
    p = np.array([10.0, 50.0, 90.0])
    np.testing.assert_allclose(mpx5100.pressure_kpa(mpx5100.output_v(p, v_supply), v_supply), p)


def test_sensor_range_flag_has_the_accuracy_band_and_keeps_values():
    p = np.array([-3.0, -2.0, 0.0, 50.0, 102.0, 103.0, 140.0])
    np.testing.assert_array_equal(
        mpx5100.beyond_sensor_range(p), [True, False, False, False, False, True, True]
    )
    # Flagging never clips: a saturating 4.9 V still converts to what it says.
    assert mpx5100.pressure_kpa(4.9) == pytest.approx((4.9 / 5 - 0.04) / 0.009)


def test_adc_range_flag_marks_the_end_codes():
    step = 20.0 / 2**14
    v = np.array([-10.0, -10.0 + step, -10.0 + 2 * step, 0.0, 9.99, 10.0 - 2 * step, 10.0 - step])
    np.testing.assert_array_equal(
        mpx5100.beyond_adc_range(v, -10.0, 10.0),
        [True, True, False, False, False, False, True],
    )


def test_zero_offset_is_the_mean_and_reports_noise():
    rng = np.random.default_rng(3)
    p = 0.7 + rng.normal(0.0, 0.05, 5000)
    zero = mpx5100.zero_offset(p, np.zeros(p.size, bool))
    assert zero.offset_kpa == pytest.approx(0.7, abs=4 * 0.05 / np.sqrt(p.size))
    assert zero.noise_kpa == pytest.approx(0.05, rel=0.05)
    assert zero.n_samples == 5000


def test_zero_refuses_a_pressurised_line_or_flagged_samples():
    with pytest.raises(DeviceError, match=r"reads 6\.00 kPa.*open the line to atmosphere"):
        mpx5100.zero_offset(np.full(100, 6.0), np.zeros(100, bool))
    flagged = np.zeros(100, bool)
    flagged[3] = True
    with pytest.raises(DeviceError, match="1 of 100 samples were beyond the DAQ's input range"):
        mpx5100.zero_offset(np.zeros(100), flagged)
    with pytest.raises(DeviceError, match="no samples"):
        mpx5100.zero_offset(np.array([]), np.array([], bool))
