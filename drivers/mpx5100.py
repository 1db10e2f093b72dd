"""The NXP MPX5100 D/G pressure sensor: its transfer function, its range and zeroing.

Pure functions over numpy arrays, so the DAQ driver, the DAQ simulator and the tests all
use the same datasheet equation and nothing here knows where the volts came from.

The sensor is ratiometric: Vout = Vs·(0.009·P + 0.04) with P in kPa (datasheet, D and G
parts), so the supply Vs is part of every conversion; measure it on a second channel
when you can rather than trusting the nominal 5.000 V.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from labrig.drivers.zeroing import zero_mean
from labrig.errors import DeviceError

SENSITIVITY_PER_KPA = 0.009  # Vout/Vs per kPa
OFFSET_RATIO = 0.04  # Vout/Vs at 0 kPa
NOMINAL_SUPPLY_V = 5.0
RANGE_KPA = (0.0, 100.0)  # D and G parts; the AP part is absolute, 15-115 kPa
SUPPLY_RANGE_V = (4.75, 5.25)  # the data sheet's supply: 5.0 V +- 5 %
# A measured supply below this is no supply (a wire cut, the supply off): the output is
# then no pressure reading, and the conversion gives NaN rather than a number.
SUPPLY_LOST_V = 0.5 * NOMINAL_SUPPLY_V
# ±2.5 % of the 4.5 V span over 0-85 °C: within this band a reading past the range ends can
# still be a true in-range pressure, so it is the tolerance of the range flag and the
# largest offset a healthy sensor shows at atmospheric pressure.
ACCURACY_KPA = 2.5
# The top of the sensor's output band: its largest full-scale output, 4.813 V at 5 V
# (100 kPa plus the accuracy). Nothing a healthy sensor at or below 100 kPa gives reads
# above it, so the rig wires a cut output wire to read above it (a pull-up to the
# supply; NAMUR NE 43: a broken wire reads outside the measuring band).
BAND_TOP_KPA = RANGE_KPA[1] + ACCURACY_KPA


def pressure_kpa(v_out: np.ndarray, v_supply: np.ndarray | float = NOMINAL_SUPPLY_V) -> np.ndarray:
    """Gauge pressure in kPa from the output voltage and the supply voltage (datasheet);
    NaN where the supply is lost (below ``SUPPLY_LOST_V``)."""
    v_supply = np.asarray(v_supply, dtype=float)
    powered = v_supply >= SUPPLY_LOST_V
    # a block's usual case, every sample powered, needs neither selection
    all_powered = bool(powered.all())
    ratio = np.asarray(v_out, dtype=float) / (
        v_supply if all_powered else np.where(powered, v_supply, 1.0)
    )
    kpa = (ratio - OFFSET_RATIO) / SENSITIVITY_PER_KPA
    return kpa if all_powered else np.where(powered, kpa, np.nan)


def output_v(p_kpa: np.ndarray, v_supply: np.ndarray | float = NOMINAL_SUPPLY_V) -> np.ndarray:
    """The ideal output voltage at a pressure: the inverse of ``pressure_kpa``."""
    return v_supply * (SENSITIVITY_PER_KPA * np.asarray(p_kpa, dtype=float) + OFFSET_RATIO)


def beyond_sensor_range(p_kpa: np.ndarray) -> np.ndarray:
    """True where a (zeroed) pressure lies outside 0-100 kPa by more than the sensor's
    accuracy, i.e. where the output may be saturated and the number is not a pressure."""
    p = np.asarray(p_kpa, dtype=float)
    return (p < RANGE_KPA[0] - ACCURACY_KPA) | (p > BAND_TOP_KPA)


def beyond_adc_range(v: np.ndarray, min_v: float, max_v: float, bits: int = 14) -> np.ndarray:
    """True where a voltage sits at or past either end of the input range.

    A saturated ADC returns its end codes, and the top code of an n-bit converter is one
    step below ``max_v``; so anything within one step of either end is suspect.
    """
    step_v = (max_v - min_v) / 2**bits
    v = np.asarray(v, dtype=float)
    return (v <= min_v + step_v) | (v >= max_v - step_v)


@dataclass(frozen=True)
class ZeroOffset:
    """The zero taken at atmospheric pressure: its value and how noisy it was."""

    offset_kpa: float
    noise_kpa: float
    n_samples: int


def zero_offset(p_raw_kpa: np.ndarray, flagged: np.ndarray) -> ZeroOffset:
    """The offset to subtract from raw readings, from samples taken at atmospheric pressure.

    The mean, because the quantisation step is small against the noise, so averaging
    gains resolution below one step. Refuses (DeviceError) when a sample was beyond the
    ADC's range or when the offset is larger than a healthy MPX5100 can show: then the
    line is not open to atmosphere, the sensor is unpowered, or the channel is wrong,
    and a zero taken there would shift every later reading.
    """
    p = np.asarray(p_raw_kpa, dtype=float)
    offset = zero_mean(p, flagged, what="pressure sensor", wiring="the sensor's wiring and supply")
    if np.any(p > BAND_TOP_KPA):
        raise DeviceError(
            f"zeroing: the sensor reads up to {np.max(p):.2f} kPa, above the MPX5100's output band "
            f"(at most {BAND_TOP_KPA:g} kPa): its output wire is open (the pull-up at the "
            "DAQ's input holds a cut wire there); check the sensor's output wire and connector"
        )
    if abs(offset) > ACCURACY_KPA:
        raise DeviceError(
            f"zeroing: the sensor reads {offset:.2f} kPa at what should be atmospheric "
            f"pressure, more than the MPX5100's ±{ACCURACY_KPA} kPa offset; open the line to "
            "atmosphere and check the channel, the sensor supply and its output wire (cut "
            "on a rig without the pull-up, it reads about 27 kPa)"
        )
    return ZeroOffset(offset_kpa=offset, noise_kpa=float(np.std(p)), n_samples=int(p.size))
