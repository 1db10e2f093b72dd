"""Scalar evaluation of a SegmentCurve for the path solver.

The quasi-static path evaluates a handful of numbers at a time, thousands of times (a
root search on a fold, one flow step, one energy difference). numpy's per-call overhead
(about a microsecond per array operation, tens of microseconds per interpolant call)
would dominate that work, so the PCHIP pieces are copied once into Python lists (for
the energies and lengths, evaluated with Horner's rule here) and into packed arrays for
the compiled pressure, slope and branch inversion (``labrig.model.actuator.curve_tables``, the
hottest calls). The numbers are those of ``SegmentCurve`` (same cubic pieces, same
linear continuation past both ends); ``SegmentCurve.volume_on_branch`` is the vectorised
counterpart of ``volume_on_branch`` here and the tests hold them equal.
"""

from __future__ import annotations

import weakref
from functools import cached_property

import numpy as np

from labrig.model.actuator import curve_tables
from labrig.model.segments.curve import SegmentCurve


class CurveKernel:
    """p(v), dp/dv, E(v), l(v) and the branch inverses of one segment, on floats."""

    def __init__(self, curve: SegmentCurve) -> None:
        self.name = curve.name
        pieces = curve.pieces
        self.x = [float(x) for x in pieces.x]
        self.last_piece = len(self.x) - 2
        self.c3, self.c2, self.c1, self.c0 = (row.tolist() for row in pieces.p_coefficients)
        self.samples = curve.p_kpa.tolist()
        self.v_first = self.x[0]
        self.v_last = self.x[-1]
        self.p_first = self.samples[0]
        self.p_last = self.samples[-1]
        self.slope_first = float(pieces.start_slope_kpa_per_ml)
        self.slope_last = float(pieces.end_slope_kpa_per_ml)
        self.lc3, self.lc2, self.lc1, self.lc0 = (row.tolist() for row in pieces.l_coefficients)
        self.branches = curve.branches
        self.n_branches = len(self.branches)
        self.peak_branch = curve.peak_branch
        self.extremum_volumes = [b.v_hi_ml for b in self.branches[:-1]]
        self.tables = curve_tables.pack([self])

    # --- forward evaluation ----------------------------------------------------------
    def _piece(self, v: float) -> int:
        return curve_tables.piece_index(self.tables, 0, v)

    def pressure(self, v: float) -> float:
        return curve_tables.pressure_and_slope(self.tables, 0, v)[0]

    def slope(self, v: float) -> float:
        return curve_tables.pressure_and_slope(self.tables, 0, v)[1]

    def pressure_and_slope(self, v: float) -> tuple[float, float]:
        return curve_tables.pressure_and_slope(self.tables, 0, v)

    def energy(self, v: float) -> float:
        """E(v) = integral of p from 0 (Eq. 1), mJ."""
        return curve_tables.energy(self.tables, 0, v)

    def energy_between(self, v_from: float, v_to: float) -> float:
        """E(v_to) - E(v_from), summed piece by piece from small terms (see ``curve_tables``)."""
        return curve_tables.energy_between(self.tables, 0, v_from, v_to)

    def length(self, v: float) -> float:
        """l(v) in mm; constant past the table's ends."""
        return curve_tables.length(self.tables, 0, v)

    def spacing_near(self, v: float) -> float:
        """Width of the table interval around v (the resolution of the curve there)."""
        j = self._piece(v)
        return self.x[j + 1] - self.x[j]

    # --- branches --------------------------------------------------------------------
    def branch_of(self, v: float) -> int:
        """Branch a volume lies on (a shared extremum sample belongs to the earlier)."""
        for index, v_end in enumerate(self.extremum_volumes):
            if v <= v_end:
                return index
        return self.n_branches - 1

    def right_of_peak(self, branch: int) -> bool:
        """On the pressure peak's falling branch or later; never, without a peak."""
        return self.peak_branch is not None and branch >= self.peak_branch

    def slope_profile(self, branch: int) -> tuple[np.ndarray, np.ndarray]:
        """(p, 1/k * sqrt(d(p))) along a branch, sorted by p, d the pressure distance to
        the nearer extremum end of the branch (``singular_weight``). Near an extremum
        1/k grows like 1/sqrt(d), so the weighted value is smooth and linear
        interpolation in p follows it closely, even where two segments near their
        peaks make the sum of two large terms of opposite sign. The points: every
        sample, the slope's extremum inside each sample interval (PCHIP's slope is a
        quadratic there and can dip below both ends, e.g. next to the contact kink),
        and points closing in on an extremum sample. Computed once per kernel, for
        ``profile_tables``."""
        return curve_tables.slope_profile(self.tables, 0, branch)

    @cached_property
    def profile_tables(self) -> tuple:
        """Every branch's slope profile as arrays (``curve_tables.pack_profiles``)."""
        return curve_tables.pack_profiles(self)

    def singular_distance(self, branch: int, p: float) -> float:
        """Pressure distance from p to the nearer end of the branch that is an
        extremum of the curve (where the slope is 0); 1.0 kPa if neither is."""
        return curve_tables.singular_distance(self.tables, 0, branch, p)

    def volume_on_branch(self, branch: int, p: float) -> tuple[float, float]:
        """(v, dp/dv) on ``branch`` at pressure ``p``; the caller keeps ``p`` within the
        branch's pressure range (values outside are clamped to its ends)."""
        return curve_tables.volume_on_branch(self.tables, 0, branch, p)


_KERNELS: weakref.WeakKeyDictionary[SegmentCurve, CurveKernel] = weakref.WeakKeyDictionary()


def kernel_of(curve: SegmentCurve) -> CurveKernel:
    """The curve's kernel, built once per curve: a scan puts the same curves in thousands
    of actuators. Kept here rather than on the curve, so that the segments package
    never imports the path solver; it lives as long as the curve does."""
    kernel = _KERNELS.get(curve)
    if kernel is None:
        kernel = _KERNELS[curve] = CurveKernel(curve)
    return kernel
