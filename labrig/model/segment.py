"""A fluidic segment as the model sees it: pressure and length against supplied volume.

Every segment source reduces to one ``SegmentCurve``, a table (v, p, l) with v the volume
supplied from the unpressurised state (zero there, as on the paper's axes). Between the
samples it is interpolated with PCHIP, which is monotone between samples and puts every
extremum exactly on a sample: a C2 spline would ring at the braid-contact kink and create
false peaks (model-notes, trap 5). So the monotone branches of p(v) are runs of samples,
and the elastic energy (Eq. 1) is the exact antiderivative of the interpolant.

Past the last sample the curve continues linearly with its end slope, so that a state a
little beyond the table is still defined; segment sources sample far enough that an
actuator never needs it in normal use.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np
from scipy.interpolate import PchipInterpolator


@dataclass(frozen=True)
class Extremum:
    """A local extremum of p(v): where it is and how high."""

    v_ml: float
    p_kpa: float


@dataclass(frozen=True, eq=False)
class SegmentCurve:
    """Tabulated p(v) and l(v) of one segment.

    ``v_ml`` starts at 0 and increases strictly; ``p_kpa`` is gauge pressure (0 at v=0);
    ``l_mm`` the segment's length; ``V0_ml`` the enclosed volume in the unpressurised
    state (for normalisations; the supplied volume does not include it).
    """

    name: str
    v_ml: np.ndarray
    p_kpa: np.ndarray
    l_mm: np.ndarray
    V0_ml: float
    source: str = ""

    def __post_init__(self) -> None:
        v = np.asarray(self.v_ml, dtype=float)
        p = np.asarray(self.p_kpa, dtype=float)
        length = np.asarray(self.l_mm, dtype=float)
        if not (v.ndim == p.ndim == length.ndim == 1 and len(v) == len(p) == len(length)):
            raise ValueError(f"{self.name}: v, p and l must be 1-D arrays of one length")
        if len(v) < 4:
            raise ValueError(f"{self.name}: a curve needs at least 4 samples, got {len(v)}")
        if not (np.all(np.isfinite(v)) and np.all(np.isfinite(p)) and np.all(np.isfinite(length))):
            raise ValueError(f"{self.name}: the curve contains NaN or infinite values")
        if np.any(np.diff(v) <= 0):
            raise ValueError(f"{self.name}: volume must increase strictly")
        for array in (v, p, length):
            array.setflags(write=False)
        object.__setattr__(self, "v_ml", v)
        object.__setattr__(self, "p_kpa", p)
        object.__setattr__(self, "l_mm", length)

    # --- interpolants --------------------------------------------------------------
    @cached_property
    def _p(self) -> PchipInterpolator:
        return PchipInterpolator(self.v_ml, self.p_kpa, extrapolate=False)

    @cached_property
    def _dp(self) -> PchipInterpolator:
        return self._p.derivative()

    @cached_property
    def _energy(self) -> PchipInterpolator:
        return self._p.antiderivative()

    @cached_property
    def _l(self) -> PchipInterpolator:
        return PchipInterpolator(self.v_ml, self.l_mm, extrapolate=False)

    @property
    def v_max_ml(self) -> float:
        return float(self.v_ml[-1])

    @cached_property
    def _end_slope_kpa_per_ml(self) -> float:
        return float(self._dp(self.v_max_ml))

    def pressure_kpa(self, v_ml):
        """p(v) in kPa; linear past the table's end."""
        v = np.asarray(v_ml, dtype=float)
        inside = np.clip(v, 0.0, self.v_max_ml)
        p = self._p(inside)
        beyond = v - self.v_max_ml
        return np.where(beyond > 0, self.p_kpa[-1] + self._end_slope_kpa_per_ml * beyond, p)

    def slope_kpa_per_ml(self, v_ml):
        """dp/dv in kPa/mL (continuous: PCHIP is C1)."""
        v = np.asarray(v_ml, dtype=float)
        inside = np.clip(v, 0.0, self.v_max_ml)
        return np.where(v > self.v_max_ml, self._end_slope_kpa_per_ml, self._dp(inside))

    def energy_mj(self, v_ml):
        """Stored elastic energy E(v) = integral of p dv from 0 (Eq. 1), in mJ
        (kPa x mL = mJ)."""
        v = np.asarray(v_ml, dtype=float)
        inside = np.clip(v, 0.0, self.v_max_ml)
        e = self._energy(inside)
        beyond = np.maximum(v - self.v_max_ml, 0.0)
        e_end = float(self._energy(self.v_max_ml))
        e_beyond = e_end + self.p_kpa[-1] * beyond + 0.5 * self._end_slope_kpa_per_ml * beyond**2
        return np.where(v > self.v_max_ml, e_beyond, e)

    def length_mm(self, v_ml):
        """Segment length l(v) in mm; constant past the table's end."""
        v = np.clip(np.asarray(v_ml, dtype=float), 0.0, self.v_max_ml)
        return self._l(v)

    # --- branch structure ----------------------------------------------------------
    @cached_property
    def extrema_indices(self) -> np.ndarray:
        """Sample indices where p(v) changes direction (interior local extrema).

        With PCHIP these are exactly the interpolant's extrema. Runs of equal samples
        (a flat plateau) count as one extremum at their last sample.
        """
        dp = np.diff(self.p_kpa)
        signs = np.sign(dp)
        # carry the previous non-zero sign through flat runs
        nonzero = np.flatnonzero(signs)
        if len(nonzero) == 0:
            return np.array([], dtype=int)
        filled = signs.copy()
        last = signs[nonzero[0]]
        for i in range(len(filled)):
            if filled[i] == 0:
                filled[i] = last
            else:
                last = filled[i]
        change = np.flatnonzero(filled[1:] != filled[:-1]) + 1
        return change

    @cached_property
    def branch_bounds(self) -> list[tuple[int, int]]:
        """Monotone branches of p(v) as (first, last) sample indices, in order of v.

        Branch 0 rises from v=0 to the peak, branch 1 falls to the valley, branch 2
        rises again, and so on; a curve with no peak is one rising branch.
        """
        edges = [0, *self.extrema_indices.tolist(), len(self.v_ml) - 1]
        return [(edges[k], edges[k + 1]) for k in range(len(edges) - 1)]

    @property
    def peak(self) -> Extremum | None:
        """The first pressure maximum (the pressure peak), or None if p(v) only rises."""
        for first, last in self.branch_bounds:
            if last < len(self.v_ml) - 1 and self.p_kpa[last] > self.p_kpa[first]:
                return Extremum(float(self.v_ml[last]), float(self.p_kpa[last]))
        return None

    @property
    def valley(self) -> Extremum | None:
        """The pressure minimum that follows the peak, or None."""
        peak = self.peak
        if peak is None:
            return None
        for first, last in self.branch_bounds:
            if self.v_ml[first] >= peak.v_ml and last < len(self.v_ml) - 1:
                return Extremum(float(self.v_ml[last]), float(self.p_kpa[last]))
        return None
