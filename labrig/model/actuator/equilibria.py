"""An actuator of n segments sharing one pressure under total-volume control: its
equilibria on a pressure grid and their stability (paper Eqs. 2-10).

The segments are connected, so at equilibrium they share one pressure (Eq. 7) and the
supplied volumes add up to the total (Eq. 2). The paper's operational method (Fig. S5)
finds every equilibrium at once: for each pressure of a grid, every volume of every
segment on every monotone branch, and every combination of those. ``equilibria`` does
exactly that, vectorised over pressures and branch combinations; it is what the v1-v2
plots show. The quasi-static path does not need the grid (``labrig.model.actuator.path``).

Stability (Eq. 10, derived here in the form used everywhere in labrig). With
v_n = v - sum_{i<n} v_i, the Hessian of the reduced energy (Eq. 9) is
H = diag(k_1..k_{n-1}) + k_n 1 1^T, with k_i = p_i'(v_i). Its quadratic form is
Q(w) = sum_i k_i w_i^2 over all w with sum_i w_i = 0, so H is positive definite iff Q > 0
on that hyperplane:
- all k_i > 0: Q > 0.
- two k_a, k_b <= 0: w = e_a - e_b gives Q = k_a + k_b <= 0: unstable.
- exactly one k_m <= 0, the others > 0: for a fixed s = sum_{i != m} w_i, the smallest
  sum_{i != m} k_i w_i^2 is s^2 / sum_{i != m} 1/k_i (Cauchy-Schwarz), so
  min Q = s^2 (1 / sum_{i != m} 1/k_i + k_m), positive iff k_m = 0 or
  sum_i 1/k_i < 0.
Equivalently det H = (prod_i k_i) * sum_i 1/k_i, which is the paper's Eq. 10 for
k = n-1; and sum_i 1/k_i = dv/dp along a branch of equilibria, so a stable state with a
segment past its peak has dv/dp < 0 and the state is lost where dv/dp crosses zero (a
fold, a turning point of v). ``is_stable`` implements this; the tests hold it equal to
the eigenvalues of the explicit Hessian and to the paper's Sylvester minors.
"""

from __future__ import annotations

import itertools
from collections.abc import Sequence
from dataclasses import dataclass
from functools import cached_property

import numpy as np

from labrig.model.actuator.curve_tables import tables_of, total_energy, total_length
from labrig.model.actuator.jit import LEAF, njit
from labrig.model.actuator.kernel import CurveKernel, kernel_of
from labrig.model.segments.curve import SegmentCurve


def is_stable(k) -> np.ndarray:
    """Stability of equilibria from the segment slopes k[..., i] = p_i'(v_i) (kPa/mL):
    the Hessian of Eq. 9 is positive definite (see the module docstring)."""
    k = np.asarray(k, dtype=float)
    nonpositive = (k <= 0).sum(axis=-1)
    with np.errstate(divide="ignore"):
        inverse_sum = (1.0 / np.where(k == 0, np.nan, k)).sum(axis=-1)
    one_soft = (nonpositive == 1) & (np.any(k == 0, axis=-1) | (inverse_sum < 0))
    return (nonpositive == 0) | one_soft


def stable_scalar(k: Sequence[float]) -> bool:
    """``is_stable`` for one state (the path solver's inner loop)."""
    return bool(stable_slopes(np.asarray(k, dtype=float)))


@njit(**LEAF)
def stable_slopes(k: np.ndarray) -> bool:
    """``is_stable`` for one state's slopes, compiled (the post-snap flow asks it at
    every step): all k_i > 0, or exactly one k_m <= 0 with k_m = 0 or sum 1/k_i < 0."""
    soft = 0
    soft_value = 0.0
    for a in k:
        if a <= 0:
            soft += 1
            soft_value = a
    if soft == 0:
        return True
    if soft > 1:
        return False
    if soft_value == 0:
        return True
    total = 0.0
    for a in k:
        total += 1.0 / a
    return total < 0


def hessian(k: Sequence[float]) -> np.ndarray:
    """The (n-1) x (n-1) Hessian of the reduced energy, Eq. 9."""
    k = np.asarray(k, dtype=float)
    return np.diag(k[:-1]) + k[-1]


@dataclass(frozen=True)
class Equilibria:
    """All equilibria found on a pressure grid, one row per equilibrium."""

    p_kpa: np.ndarray  # (M,)
    v_i_ml: np.ndarray  # (M, n) supplied volume of each segment
    branches: np.ndarray  # (M, n) branch index of each segment
    stable: np.ndarray  # (M,) bool

    @property
    def v_ml(self) -> np.ndarray:
        """Total supplied volume of each equilibrium (Eq. 2)."""
        return self.v_i_ml.sum(axis=1)


class Actuator:
    """n segments connected in series, sharing one pressure (volume-controlled)."""

    def __init__(self, segments: Sequence[SegmentCurve]) -> None:
        if len(segments) < 2:
            raise ValueError(f"an actuator needs at least two segments, got {len(segments)}")
        self.segments = tuple(segments)

    @property
    def n(self) -> int:
        return len(self.segments)

    @property
    def names(self) -> list[str]:
        return [s.name for s in self.segments]

    @cached_property
    def kernels(self) -> tuple[CurveKernel, ...]:
        return tuple(kernel_of(s) for s in self.segments)

    def energy_mj(self, v_i_ml: Sequence[float]) -> float:
        """Total stored energy, Eq. 3 (from the unpressurised state)."""
        return total_energy(tables_of(self.kernels), np.asarray(v_i_ml, dtype=float))

    def length_mm(self, v_i_ml: Sequence[float]) -> float:
        """Actuator length: the sum of the segment lengths."""
        return total_length(tables_of(self.kernels), np.asarray(v_i_ml, dtype=float))

    def alpha(self, branches: Sequence[int]) -> int:
        """Number of segments to the right of their pressure peak (the paper's alpha,
        beta). A segment without a peak is never right of it."""
        return sum(kern.right_of_peak(b) for kern, b in zip(self.kernels, branches, strict=True))

    def equilibria(self, p_kpa) -> Equilibria:
        """Every equilibrium at the given pressures (the paper's Fig. S5 method)."""
        p = np.atleast_1d(np.asarray(p_kpa, dtype=float))
        per_segment = [s.volumes_at_pressure(p) for s in self.segments]
        combos = np.array(list(itertools.product(*(range(len(s.branches)) for s in self.segments))))
        v = np.stack([per_segment[i][0][:, combos[:, i]] for i in range(self.n)], axis=-1)
        k = np.stack([per_segment[i][1][:, combos[:, i]] for i in range(self.n)], axis=-1)
        found = np.all(np.isfinite(v), axis=-1)  # (P, C)
        rows, cols = np.nonzero(found)
        return Equilibria(
            p_kpa=p[rows],
            v_i_ml=v[rows, cols],
            branches=combos[cols],
            stable=is_stable(k[rows, cols]),
        )

    def pressure_grid(self, n_points: int = 1000, p_max_kpa: float = 100.0) -> np.ndarray:
        """The paper's equispaced pressure grid, 0..p_max (1,000 points to 100 kPa)."""
        return np.linspace(0.0, p_max_kpa, n_points)
