"""One repetition's measurement as the live page plots it: pressure and length against
supplied volume, built from the samples as they are appended to the run file.

The pressure arrives at 1 kHz and the pump's volume at its poll rate (a few readings a
second), on the same clock. The page needs neither every sample nor more than a few
points per second of rig time, so the pressure is averaged into bins of ``bin_s``
(out-of-range samples left out) and the length is kept per frame (frames where both
markers were found). A point gets its volume only once a pump reading at or after its
time exists, by linear interpolation between the pump readings around it, as the
analysis does (``labrig.analysis.curves.volume_at``); until then it waits. So every
point the page shows has the volume it will have in the analysis, and none is ever
revised.

The binned series are also what the live transition detection reads: the same
detector as the analysis, on 20 samples per second instead of 1000 (a snap takes about
a second; ``labrig.live.state``).
"""

from __future__ import annotations

import numpy as np

from labrig.analysis.curves import volume_at


class RepetitionSeries:
    """The binned pressure, the length and the pump log of one repetition.

    Not thread-safe: one digest thread feeds it (``labrig.live.state``). Points whose
    volume is known are appended to ``pressure_points`` / ``length_points`` as
    ``(t_s, v_ml, value)`` and never change.
    """

    def __init__(self, repetition: int, bin_s: float = 0.05) -> None:
        self.repetition = repetition
        self.bin_s = bin_s
        self.pump_t: list[float] = []
        self.pump_v: list[float] = []
        self.pressure_points: list[tuple[float, float, float]] = []
        self.length_points: list[tuple[float, float, float]] = []
        self._bin: int | None = None  # the bin still filling
        self._bin_sum = 0.0
        self._bin_n = 0
        self._waiting_p: list[tuple[float, float]] = []  # (t, p) without a volume yet
        self._waiting_l: list[tuple[float, float]] = []

    # --- feeding ---------------------------------------------------------------------
    def add_pressure(self, t_s: np.ndarray, p_kpa: np.ndarray, out_of_range: np.ndarray) -> None:
        good = np.isfinite(p_kpa) & ~np.asarray(out_of_range, dtype=bool)
        t_s, p_kpa = np.asarray(t_s, float)[good], np.asarray(p_kpa, float)[good]
        if not len(t_s):
            return
        bins = np.floor(t_s / self.bin_s).astype(np.int64)
        first = int(bins[0])
        if self._bin is not None and first > self._bin:
            self._close_bin()
        edges = np.flatnonzero(np.diff(bins)) + 1
        starts = np.concatenate([[0], edges])
        ends = np.concatenate([edges, [len(bins)]])
        for start, end in zip(starts, ends, strict=True):
            b = int(bins[start])
            if self._bin is not None and b != self._bin:
                self._close_bin()
            self._bin = b
            self._bin_sum += float(p_kpa[start:end].sum())
            self._bin_n += end - start
        # the last bin may still receive samples from the next block
        self._resolve()

    def add_length(self, t_s: np.ndarray, length_mm: np.ndarray, ok: np.ndarray) -> None:
        good = np.asarray(ok, dtype=bool) & np.isfinite(length_mm)
        t_s, length_mm = np.asarray(t_s, float)[good], np.asarray(length_mm, float)[good]
        self._waiting_l += list(zip(t_s.tolist(), length_mm.tolist(), strict=True))
        self._resolve()

    def add_pump(self, t_s: np.ndarray, volume_ml: np.ndarray) -> None:
        self.pump_t += np.asarray(t_s, float).tolist()
        self.pump_v += np.asarray(volume_ml, float).tolist()
        self._resolve()

    def _close_bin(self) -> None:
        if self._bin_n:
            t_mid = (self._bin + 0.5) * self.bin_s
            self._waiting_p.append((t_mid, self._bin_sum / self._bin_n))
        self._bin, self._bin_sum, self._bin_n = None, 0.0, 0

    def _resolve(self) -> None:
        """Give every waiting point whose time the pump log now covers its volume."""
        if not self.pump_t:
            return
        t_last = self.pump_t[-1]
        for waiting, points in (
            (self._waiting_p, self.pressure_points),
            (self._waiting_l, self.length_points),
        ):
            ready = [w for w in waiting if w[0] <= t_last]
            if not ready:
                continue
            del waiting[: len(ready)]
            t = np.array([w[0] for w in ready])
            v = volume_at(t, np.asarray(self.pump_t), np.asarray(self.pump_v))
            points += [
                (ti, vi, w[1]) for ti, vi, w in zip(t.tolist(), v.tolist(), ready, strict=True)
            ]

    # --- reading (the digest thread) ---------------------------------------------------
    def arrays(self) -> dict[str, np.ndarray]:
        """The series as arrays for the transition detector."""
        p = np.asarray(self.pressure_points, dtype=float).reshape(-1, 3)
        length = np.asarray(self.length_points, dtype=float).reshape(-1, 3)
        return {
            "pressure_t_s": p[:, 0],
            "pressure_kpa": p[:, 2],
            "pump_t_s": np.asarray(self.pump_t),
            "pump_v_ml": np.asarray(self.pump_v),
            "length_t_s": length[:, 0],
            "length_mm": length[:, 2],
        }
