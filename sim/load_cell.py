"""A simulated load cell and bridge amplifier: the plant's force as the amplifier's volts.

Wired into ``SimDaqTask`` as another input's signal, so the real driver
(``labrig.drivers.ni_daq_force``) reads it through the nidaqmx API like the pressure. The
amplifier is off by ``offset_error_n`` at no load (what zeroing removes) and adds white
noise; the DAQ quantises the rest.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from labrig.drivers import load_cell


class LoadCellSignal:
    """The amplifier's output volts at sample times, for a force ``force_n_at(t_s)``."""

    def __init__(
        self,
        force_n_at: Callable[[np.ndarray], np.ndarray],
        *,
        n_per_v: float,
        offset_v: float = 0.0,
        offset_error_n: float = 0.3,
        noise_n: float = 0.02,
        seed: int | None = None,
    ) -> None:
        self.force_n_at = force_n_at
        self.n_per_v = float(n_per_v)
        self.offset_v = float(offset_v)
        self.offset_error_n = float(offset_error_n)
        self.noise_n = float(noise_n)
        self._rng = np.random.default_rng(seed)

    def __call__(self, t_s: np.ndarray) -> np.ndarray:
        f = np.asarray(self.force_n_at(t_s), dtype=float) + self.offset_error_n
        if self.noise_n > 0:
            f = f + self._rng.normal(0.0, self.noise_n, f.shape)
        return load_cell.output_v(f, self.n_per_v, self.offset_v)
