"""Taking a sensor's zero: the mean of readings taken unloaded, refused when it cannot be
a zero. Shared by the pressure sensor's and the load cell's conversions."""

from __future__ import annotations

import numpy as np

from labrig.errors import DeviceError


def zero_mean(values: np.ndarray, flagged: np.ndarray, *, what: str, wiring: str) -> float:
    """The mean of ``values``; DeviceError when there are none or any was beyond the
    DAQ's range (``what`` names the sensor, ``wiring`` what to check)."""
    v = np.asarray(values, dtype=float)
    if v.size == 0:
        raise DeviceError(f"zeroing got no samples from the {what}")
    if np.any(flagged):
        raise DeviceError(
            f"zeroing the {what}: {int(np.count_nonzero(flagged))} of {v.size} samples were "
            f"beyond the DAQ's input range; check {wiring}"
        )
    return float(np.mean(v))
