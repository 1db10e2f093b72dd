"""What a measured table can resolve: its volume spacing, its pressure quantisation step
and its noise, all estimated from the numbers themselves.

A table written by another tool or read off a rig has a resolution of its own, which the
model must respect rather than the library's: a curve rounded to 0.01 kPa is a staircase
whose plateaus are not physical (a flat piece of p(v) has zero stiffness and would make
folds), a raw 1 kHz log has noise larger than the change of p between rows, so that every
local extremum but the peak and the valley is spurious. ``TableResolution`` carries the
three numbers, and ``prominence_kpa`` turns them into the smallest dip (peak minus
valley) the table can be trusted to show.

- spacing: the median volume step between rows (and the extremes, to call the table
  uniform or not);
- step: the largest q such that every distinct pressure is on a lattice o + k q to
  within the decimals it was written with (a sensor's ADC lattice, offset or not, a
  0.5 kPa staircase written with one decimal), or, failing that, the decimal to which
  every pressure was rounded; 0 when the values are full-precision;
- noise: the robust standard deviation of each row's residual from the cubic through
  its four neighbours (exact for any cubic trend, so curvature of a sparse table does
  not count as noise), with the quantisation step's own error included (a staircase
  sampled finer than its step shows none: its residuals are mostly 0).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

# A dip counts only if it stands out of the table's resolution by these factors: a
# one-step rounding wiggle is one step (two at a row next to a jump), and four noise
# standard deviations are exceeded by chance once in ~30,000 rows
STEP_PROMINENCE = 3.0
NOISE_PROMINENCE = 4.0
# relative size of float rounding in the pressures (a difference smaller is 0)
_FLOAT_FLOOR = 1e-12
_MAX_DECIMALS = 10
_LATTICE_DIVISORS = 16
_LATTICE_OVER_DECIMALS = 2.5  # a lattice must be this much coarser than the decimals
_EXACT_OVER_DECIMALS = 2.0  # ... or an exact multiple of them this much coarser
_MIN_LEVELS = 8  # fewer distinct values tell no lattice
ROUTE_TABULATED = "tabulated"
ROUTE_FITTED = "fitted"


@dataclass(frozen=True)
class TableResolution:
    """The resolution of a measured table (see the module docstring)."""

    rows: int
    spacing_ml: float  # median volume step
    spacing_min_ml: float
    spacing_max_ml: float
    step_kpa: float  # quantisation step; 0 for full-precision values
    noise_kpa: float  # robust standard deviation of the residuals

    @property
    def uniform(self) -> bool:
        """Rows evenly spaced in volume (to 1 %)."""
        return self.spacing_max_ml <= 1.01 * self.spacing_min_ml

    @property
    def prominence_kpa(self) -> float:
        """The smallest peak-to-valley dip this table resolves."""
        return max(STEP_PROMINENCE * self.step_kpa, NOISE_PROMINENCE * self.noise_kpa)

    @property
    def quantised(self) -> bool:
        """The noise is no more than the quantisation's own error: a clean staircase."""
        return self.noise_kpa <= 0.5 * self.step_kpa

    def describe(self) -> str:
        spacing = (
            f"spacing {self.spacing_ml:.4g} mL"
            if self.uniform
            else f"spacing {self.spacing_min_ml:.4g}..{self.spacing_max_ml:.4g} mL "
            f"(median {self.spacing_ml:.4g})"
        )
        step = f"step {self.step_kpa:.3g} kPa" if self.step_kpa > 0 else "full-precision values"
        return f"{self.rows} rows, {spacing}, {step}, noise {self.noise_kpa:.3g} kPa"


@dataclass(frozen=True)
class MeasuredImport:
    """What was done to a measured table to make its curve: the table's resolution, the
    route (``ROUTE_TABULATED``: its rows, plateaus collapsed; ``ROUTE_FITTED``: the
    robust rise-fall-rise fit), whether a peak (and its valley) was kept and how deep
    its dip is, the smallest dip that counted (the resolution's prominence, or 0 for an
    undithered staircase that shows its dip: ``stair_edges.shows_dip``), and the raw
    rows (for plots)."""

    resolution: TableResolution
    route: str
    peak_kept: bool
    dip_kpa: float
    min_dip_kpa: float
    notes: tuple[str, ...]
    raw: np.ndarray  # (rows, 3): volume_ml, pressure_kpa, length_mm as read


def resolution_of(v_ml, p_kpa) -> TableResolution:
    """The spacing, step and noise of the table (v, p): v strictly increasing."""
    v = np.asarray(v_ml, dtype=float)
    p = np.asarray(p_kpa, dtype=float)
    dv = np.diff(v)
    step = quantisation_step(p)
    return TableResolution(
        rows=len(v),
        spacing_ml=float(np.median(dv)),
        spacing_min_ml=float(dv.min()),
        spacing_max_ml=float(dv.max()),
        step_kpa=step,
        noise_kpa=residual_noise(v, p),
    )


def quantisation_step(p_kpa) -> float:
    """The pressure lattice of the table (see the module docstring); 0 if none.

    The lattice is searched among the distinct values (its levels), whatever decimals
    they were written with: an ADC's 0.0271 kPa counts printed to 2 decimals are 0.02 or
    0.03 apart, a 0.5 kPa staircase printed to 1 decimal is on the 0.1 kPa decimals
    too. A candidate step comes from the smallest gap between levels g (one step, or a
    few where the rows skip levels): the mean of the gaps within a decimal of g (each
    one step written to the decimals: their mean is the step to a decimal over their
    number) over 1, 2, ... steps. Each gap is then a whole number of steps, so each
    level has its count k, and the step is taken when some lattice o + k q holds every
    level to within half a decimal (the Chebyshev fit, ``_lattice_fit``). The largest
    such step at least ``_LATTICE_OVER_DECIMALS`` decimals wins, else the decimal."""
    p = np.asarray(p_kpa, dtype=float)
    scale = max(float(np.max(np.abs(p))), 1.0)
    floor = _FLOAT_FLOOR * scale
    decimal = _decimal_step(p, floor)
    levels = np.unique(p)
    gaps = np.diff(levels)
    if len(levels) < _MIN_LEVELS or gaps.min() <= floor:
        return decimal
    written = 0.5 * decimal + 4 * floor  # how far a level may be off its lattice point
    smallest = float(gaps.min())
    near = gaps[gaps <= smallest + 1.01 * decimal + 4 * floor]
    one_gap = float(near.mean())
    for divisor in range(1, _LATTICE_DIVISORS + 1):
        q = one_gap / divisor
        if q < _EXACT_OVER_DECIMALS * decimal - written or q <= 1e3 * floor:
            break  # a lattice not coarser than the decimals is the decimals
        # refine q on gaps of ever more steps: a gap of m steps gets its count right
        # while m times the error of q is well within half a step
        reach = 2.0  # in smallest gaps: never none
        while True:
            small = gaps <= reach * one_gap
            counts = np.round(gaps[small] / q)
            if np.any(counts < 1):
                break
            q = float(np.sum(gaps[small]) / np.sum(counts))
            if np.all(small):
                break
            reach *= 4.0
        counts = np.round(gaps / q)
        if np.any(counts < 1):
            continue
        k = np.r_[0.0, np.cumsum(counts)]
        # between 2 and 2.5 decimals only an exact multiple of the decimal is told from
        # the decimals themselves (every decimal is within half of one of such a lattice)
        tolerance = written if q >= _LATTICE_OVER_DECIMALS * decimal else 4 * floor
        lattice = _lattice_fit(k, levels, tolerance)
        if lattice is not None:
            return max(lattice, decimal)
    return decimal


def _lattice_fit(k: np.ndarray, levels: np.ndarray, tolerance_kpa: float) -> float | None:
    """The step q of a lattice o + k q that holds every level within ``tolerance_kpa``,
    or None. The least-squares line decides the clear cases; where its largest residual
    is within twice the tolerance, the line of least largest residual (a linear
    programme in o, q and that residual) decides."""
    q, o = np.polyfit(k, levels, 1)
    worst = float(np.max(np.abs(levels - o - k * q)))
    if worst <= tolerance_kpa:
        return float(q)
    if worst > 2 * tolerance_kpa:
        return None
    from scipy.optimize import linprog

    # minimise r subject to |level - o - k q| <= r
    ones = np.ones_like(k)
    a_ub = np.r_[np.c_[-ones, -k, -ones], np.c_[ones, k, -ones]]
    b_ub = np.r_[-levels, levels]
    result = linprog(
        [0.0, 0.0, 1.0], A_ub=a_ub, b_ub=b_ub, bounds=[(None, None)] * 3, method="highs"
    )
    if result.status != 0 or result.x[2] > tolerance_kpa:
        return None
    return float(result.x[1])


def _decimal_step(p: np.ndarray, floor: float) -> float:
    """10^-d for the fewest decimals d to which every value is rounded; 0 if more than
    ``_MAX_DECIMALS`` (full precision, as far as a table can tell)."""
    for decimals in range(_MAX_DECIMALS + 1):
        q = 10.0**-decimals
        if q < 1e3 * floor:  # rounding to q would not be told from float rounding
            break
        if np.all(np.abs(p - np.round(p / q) * q) <= 4 * floor):
            return q
    return 0.0


def residual_noise(v_ml, p_kpa) -> float:
    """Robust standard deviation of the residuals of each row from the cubic through
    its two neighbours on either side (1.4826 x the median absolute residual, each
    residual divided by its own noise gain sqrt(1 + sum of the cubic's weights^2))."""
    v = np.asarray(v_ml, dtype=float)
    p = np.asarray(p_kpa, dtype=float)
    if len(v) < 5:
        return 0.0
    x = v[2:-2]
    nodes = [v[:-4], v[1:-3], v[3:-1], v[4:]]
    values = [p[:-4], p[1:-3], p[3:-1], p[4:]]
    weights = []
    for j, xj in enumerate(nodes):
        w = np.ones_like(x)
        for m, xm in enumerate(nodes):
            if m != j:
                w = w * (x - xm) / (xj - xm)
        weights.append(w)
    predicted = sum(w * y for w, y in zip(weights, values, strict=True))
    gain = np.sqrt(1.0 + sum(w * w for w in weights))
    return float(1.4826 * np.median(np.abs(p[2:-2] - predicted) / gain))
