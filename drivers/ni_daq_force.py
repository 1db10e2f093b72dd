"""The pressure acquisition with a load cell on another input of the same USB-6009.

A USB-6009 runs one analog-input task at a time, so the load cell's amplifier output is
one more channel of the pressure task, sampled at the same rate on the same clock:
each ``PressureBlock`` comes with the force at the same instants. Everything else (the
task, its timing, errors and zero) is ``NiDaqPressure``'s; this adds the channel, its
conversion (``labrig.drivers.load_cell``) and its zero.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from labrig.drivers import load_cell, mpx5100
from labrig.drivers.ni_daq import NiDaqPressure
from labrig.errors import InputError
from labrig.rig.devices import PressureBlock


@dataclass(frozen=True)
class PressureForceBlock(PressureBlock):
    """Pressure samples and the force (N, zeroed, compression positive) at their times."""

    force_n: np.ndarray = field(kw_only=True)


class NiDaqPressureForce(NiDaqPressure):
    """``NiDaqPressure`` plus a load cell on ``force_channel`` (same terminal mode)."""

    measures_force = True

    def __init__(
        self,
        *args,
        force_channel: str,
        n_per_v: float,
        offset_v: float = 0.0,
        capacity_n: float = 100.0,
        **kwargs,
    ) -> None:
        super().__init__(*args, **kwargs)
        if not n_per_v > 0 or not capacity_n > 0:
            raise InputError(
                f"load cell: n_per_v ({n_per_v}) and capacity_n ({capacity_n}) must be > 0"
            )
        if force_channel in self.channels:
            raise InputError(f"load cell channel {force_channel} is already the pressure's")
        self.channels.append(force_channel)
        self.n_per_v = float(n_per_v)
        self.offset_v = float(offset_v)
        self.capacity_n = float(capacity_n)
        self.force_offset_n = 0.0

    def _raw_force(self, data: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        (low_v, high_v), bits = self.adc_ranges_v[-1], self.adc_bits[-1]
        flags = mpx5100.beyond_adc_range(data[-1], low_v, high_v, bits)
        return load_cell.force_n(data[-1], self.n_per_v, self.offset_v), flags

    def _take_zero(self, data: np.ndarray) -> None:
        super()._take_zero(data)
        f_raw_n, flags = self._raw_force(data)
        self.force_offset_n = load_cell.zero_offset_n(f_raw_n, flags, self.capacity_n)

    def _block(self, data: np.ndarray) -> PressureForceBlock:
        block = super()._block(data)
        f_raw_n, flags = self._raw_force(data)
        force = f_raw_n - self.force_offset_n
        # a saturated force channel is kept as measured, flagged like the pressure
        out_of_range = block.out_of_range | flags | (np.abs(force) > self.capacity_n)
        return PressureForceBlock(
            block.t_s, block.pressure_kpa, out_of_range, block.wire_open, force_n=force
        )
