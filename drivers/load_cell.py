"""A strain-gauge load cell behind a bridge amplifier: volts to newtons, and its zero.

Pure functions over numpy arrays, like ``labrig.drivers.mpx5100``: the DAQ driver, its
simulator and the tests share one transfer function. The amplifier's output is linear,
F = n_per_v (V - offset_v), with the calibration (N/V and the output at no load) from
the amplifier's sheet or a dead-weight check, kept in the rig file. Before each run the
zero is taken again with the actuator unpressurised, as the pressure sensor's is: a
bridge drifts with temperature by more than its resolution.
"""

from __future__ import annotations

import numpy as np

from labrig.drivers.zeroing import zero_mean
from labrig.errors import DeviceError


def force_n(v: np.ndarray, n_per_v: float, offset_v: float = 0.0) -> np.ndarray:
    """Force in N (compression positive, as the amplifier is wired) from its output."""
    return n_per_v * (np.asarray(v, dtype=float) - offset_v)


def output_v(f_n: np.ndarray, n_per_v: float, offset_v: float = 0.0) -> np.ndarray:
    """The amplifier's output at a force: the inverse of ``force_n``."""
    return offset_v + np.asarray(f_n, dtype=float) / n_per_v


def zero_offset_n(f_raw_n: np.ndarray, flagged: np.ndarray, capacity_n: float) -> float:
    """The force to subtract from later readings, from samples taken unloaded.

    Refuses (DeviceError) a zero taken on a saturated input, or one larger than a tenth
    of the cell's capacity: then the actuator is already loaded, or the channel or the
    calibration is wrong, and every later force would be shifted by it.
    """
    offset = zero_mean(
        f_raw_n, flagged, what="load cell", wiring="the amplifier's wiring and supply"
    )
    if abs(offset) > 0.1 * capacity_n:
        raise DeviceError(
            f"load cell zero: it reads {offset:.2f} N unloaded, more than a tenth of its "
            f"{capacity_n:g} N capacity; unload the actuator and check the channel, "
            "n_per_v and offset_v in the rig file"
        )
    return offset
