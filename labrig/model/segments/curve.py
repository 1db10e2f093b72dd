"""A fluidic segment as the model sees it: pressure and length against supplied volume.

Every segment source reduces to one ``SegmentCurve``, a table (v, p, l) with v the volume
supplied from the unpressurised state (zero there, as on the paper's axes). Between the
samples it is interpolated with PCHIP, which is monotone between samples and puts every
extremum exactly on a sample: a C2 spline would ring at the braid-contact kink and create
false peaks, each a transition no segment has. So the monotone branches of p(v) are runs of samples,
and the elastic energy (Eq. 1) is the exact antiderivative of the interpolant.

Past the last sample the curve continues linearly with its end slope, so that a state a
little beyond the table is still defined; segment sources sample far enough that an
actuator never needs it in normal use. Below v = 0 it continues linearly with its initial
slope (a segment drained below its unpressurised volume has a negative gauge pressure), so
that a minimiser or a flow probing v < 0 sees a smooth, convex energy rather than a flat one.

The actuator model works branch by branch: ``branches`` lists the monotone runs of p(v)
and ``volume_on_branch`` inverts one of them (all volumes at which a segment has a given
pressure, the paper's operational method, Fig. S5A).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property

import numpy as np

from labrig.model.segments.resolution import MeasuredImport


@dataclass(frozen=True)
class PchipPieces:
    """What the path solver's kernels read of a curve (``labrig.model.actuator.kernel``):
    the breakpoints and cubic coefficients of its PCHIP for p(v) and l(v), in scipy's
    ``PPoly`` layout (highest power first, a column per piece), and p's slopes at the two
    ends. Apart from the interpolants so that a library read from a scan's cache gives
    them as stored, without importing scipy's interpolation, which was most of a warm
    scan's start-up."""

    x: np.ndarray
    p_coefficients: np.ndarray
    l_coefficients: np.ndarray
    start_slope_kpa_per_ml: float
    end_slope_kpa_per_ml: float


class PiecewisePolynomial:
    """A piecewise polynomial in scipy's ``PPoly`` layout (highest power first, a column
    per piece between breakpoints ``x``), evaluated, differentiated and integrated with
    numpy in the same operations and order as ``PPoly`` without extrapolation, so the
    same bits: a curve read with its pieces from the cache is evaluated without
    importing scipy's interpolation, most of a simulated run's start-up."""

    def __init__(self, x: np.ndarray, coefficients: np.ndarray) -> None:
        self.x = x
        self.c = coefficients

    def __call__(self, v):
        """The value at ``v`` (NaN outside the breakpoints): ``PPoly``'s sum from the
        constant term up, the power of the offset built by repeated products."""
        v = np.asarray(v, dtype=float)
        x = self.x
        # half-open pieces [x_k, x_k+1), the last one closed
        k = np.clip(np.searchsorted(x, v, side="right") - 1, 0, len(x) - 2)
        with np.errstate(invalid="ignore"):  # an infinite v: NaN, as out of range
            total = _power_sum([row[k] for row in self.c], v - x[k])
        return np.where((v >= x[0]) & (v <= x[-1]), total, np.nan)

    def derivative(self) -> PiecewisePolynomial:
        """d/dv, as ``PPoly.derivative``: each power's coefficient times the power."""
        powers = np.arange(len(self.c) - 1, 0, -1, dtype=float)
        return PiecewisePolynomial(self.x, self.c[:-1] * powers[:, None])

    def antiderivative(self) -> PiecewisePolynomial:
        """The integral from ``x[0]``, as ``PPoly.antiderivative``: each coefficient
        over its new power, and each piece's constant the previous piece's value at
        its end, piece after piece."""
        c = np.zeros((len(self.c) + 1, self.c.shape[1]))
        c[:-1] = self.c / np.arange(len(self.c), 0, -1, dtype=float)[:, None]
        rows = c.tolist()
        for piece in range(1, len(self.x) - 1):
            s = float(self.x[piece] - self.x[piece - 1])
            rows[-1][piece] = _power_sum([row[piece - 1] for row in rows], s)
        c[-1] = rows[-1]
        return PiecewisePolynomial(self.x, c)


def _power_sum(coefficients, s):
    """sum c_r s^(m-r) over the coefficients, highest power first, in ``PPoly``'s order:
    from the constant term up, each power of ``s`` the product of the one before (so the
    same bits as scipy). For arrays of pieces or for one piece's plain floats."""
    total = 0.0 + coefficients[-1]
    power = s
    for row in range(len(coefficients) - 2, -1, -1):
        total = total + coefficients[row] * power
        if row:
            power = power * s
    return total


@dataclass(frozen=True)
class Extremum:
    """A local extremum of p(v): where it is and how high."""

    v_ml: float
    p_kpa: float


@dataclass(frozen=True)
class Branch:
    """One monotone run of p(v), samples ``first``..``last``.

    ``p_lo_kpa``..``p_hi_kpa`` is the pressure range over which the branch can be
    inverted. It is the range of its samples, except that the last branch extends to
    +inf (rising) or -inf (falling) with the table's linear continuation, so that an
    actuator can always be inflated further.
    """

    index: int
    first: int
    last: int
    rising: bool
    v_lo_ml: float
    v_hi_ml: float
    p_lo_kpa: float
    p_hi_kpa: float


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
    # for a measured table: its resolution and what was done to it (``measured.py``)
    measured: MeasuredImport | None = field(default=None, repr=False)

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

    @classmethod
    def with_pieces(cls, pieces: PchipPieces, **fields) -> SegmentCurve:
        """The curve of ``fields`` whose PCHIP pieces are known already (stored with its
        tables by ``labrig.model.segments.curve_cache``): they and the end slopes are not
        computed again, and scipy is not imported at all."""
        curve = cls(**fields)
        curve.__dict__["pieces"] = pieces
        return curve

    # --- interpolants --------------------------------------------------------------
    @cached_property
    def pieces(self) -> PchipPieces:
        """scipy's PCHIP of the tables: imported here, at a curve's first evaluation and
        not with this module, since a curve given its pieces never needs it."""
        from scipy.interpolate import PchipInterpolator

        pressure = PchipInterpolator(self.v_ml, self.p_kpa)
        slope = PiecewisePolynomial(pressure.x, pressure.c).derivative()
        return PchipPieces(
            pressure.x,
            pressure.c,
            PchipInterpolator(self.v_ml, self.l_mm).c,
            float(slope(self.v_ml[0])),
            float(slope(self.v_max_ml)),
        )

    @cached_property
    def _p(self) -> PiecewisePolynomial:
        return PiecewisePolynomial(self.pieces.x, self.pieces.p_coefficients)

    @cached_property
    def _dp(self) -> PiecewisePolynomial:
        return self._p.derivative()

    @cached_property
    def _energy(self) -> PiecewisePolynomial:
        return self._p.antiderivative()

    @cached_property
    def _l(self) -> PiecewisePolynomial:
        return PiecewisePolynomial(self.pieces.x, self.pieces.l_coefficients)

    @property
    def _end_slope_kpa_per_ml(self) -> float:
        return self.pieces.end_slope_kpa_per_ml

    @property
    def _start_slope_kpa_per_ml(self) -> float:
        return self.pieces.start_slope_kpa_per_ml

    @property
    def v_max_ml(self) -> float:
        return float(self.v_ml[-1])

    def pressure_kpa(self, v_ml):
        """p(v) in kPa; linear past both ends of the table."""
        v = np.asarray(v_ml, dtype=float)
        inside = np.clip(v, self.v_ml[0], self.v_max_ml)
        p = self._p(inside)
        beyond = v - self.v_max_ml
        before = v - self.v_ml[0]
        p = np.where(beyond > 0, self.p_kpa[-1] + self._end_slope_kpa_per_ml * beyond, p)
        return np.where(before < 0, self.p_kpa[0] + self._start_slope_kpa_per_ml * before, p)

    def slope_kpa_per_ml(self, v_ml):
        """dp/dv in kPa/mL (continuous: PCHIP is C1, and so are the linear ends)."""
        v = np.asarray(v_ml, dtype=float)
        inside = np.clip(v, self.v_ml[0], self.v_max_ml)
        k = np.where(v > self.v_max_ml, self._end_slope_kpa_per_ml, self._dp(inside))
        return np.where(v < self.v_ml[0], self._start_slope_kpa_per_ml, k)

    def energy_mj(self, v_ml):
        """Stored elastic energy E(v) = integral of p dv from 0 (Eq. 1), in mJ
        (kPa x mL = mJ)."""
        v = np.asarray(v_ml, dtype=float)
        inside = np.clip(v, self.v_ml[0], self.v_max_ml)
        e = self._energy(inside)
        beyond = np.maximum(v - self.v_max_ml, 0.0)
        e_end = float(self._energy(self.v_max_ml))
        e_beyond = e_end + self.p_kpa[-1] * beyond + 0.5 * self._end_slope_kpa_per_ml * beyond**2
        before = np.minimum(v - self.v_ml[0], 0.0)
        e_before = self.p_kpa[0] * before + 0.5 * self._start_slope_kpa_per_ml * before**2
        return np.where(v > self.v_max_ml, e_beyond, np.where(v < self.v_ml[0], e_before, e))

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

    @cached_property
    def branches(self) -> tuple[Branch, ...]:
        """The monotone branches with their volume and invertible pressure ranges."""
        out = []
        bounds = self.branch_bounds
        for index, (first, last) in enumerate(bounds):
            rising = bool(self.p_kpa[last] > self.p_kpa[first])
            p_lo = float(min(self.p_kpa[first], self.p_kpa[last]))
            p_hi = float(max(self.p_kpa[first], self.p_kpa[last]))
            if index == len(bounds) - 1:
                if rising and self._end_slope_kpa_per_ml > 0:
                    p_hi = np.inf
                elif not rising and self._end_slope_kpa_per_ml < 0:
                    p_lo = -np.inf
            out.append(
                Branch(
                    index,
                    first,
                    last,
                    rising,
                    float(self.v_ml[first]),
                    float(self.v_ml[last]),
                    p_lo,
                    p_hi,
                )
            )
        return tuple(out)

    @cached_property
    def peak_branch(self) -> int | None:
        """Index of the branch that starts at the pressure peak (the first falling
        branch), or None for a curve without a peak. A segment is "right of its peak"
        when it is on this branch or a later one."""
        peak = self.peak
        if peak is None:
            return None
        return next(b.index for b in self.branches if b.v_lo_ml >= peak.v_ml)

    def branch_of_volume(self, v_ml):
        """Index of the branch a volume lies on; a shared end sample (an extremum)
        belongs to the earlier branch."""
        ends = np.array([b.v_hi_ml for b in self.branches[:-1]])
        return np.searchsorted(ends, np.asarray(v_ml, dtype=float), side="left")

    def volume_on_branch(self, branch: int, p_kpa) -> tuple[np.ndarray, np.ndarray]:
        """Volumes (mL) and slopes dp/dv (kPa/mL) at which the segment has pressure
        ``p_kpa`` on one monotone branch; NaN outside the branch's pressure range.

        Vectorised over pressures. On a branch the PCHIP interpolant is a monotone cubic
        between samples, so each pressure has one volume: the interval is found by
        bisection of the samples, the cubic is solved by Newton's method kept inside the
        interval by bisection. The result is exact to ~1e-13 of the sample spacing.
        """
        b = self.branches[branch]
        p = np.atleast_1d(np.asarray(p_kpa, dtype=float))
        v_out = np.full(p.shape, np.nan)
        k_out = np.full(p.shape, np.nan)
        inside = (p >= b.p_lo_kpa) & (p <= b.p_hi_kpa)
        p_end = self.p_kpa[b.last]
        # the linear continuation past the table's last sample
        past = inside & ((p > p_end) if b.rising else (p < p_end)) & (b.last == len(self.v_ml) - 1)
        if np.any(past):
            slope = self._end_slope_kpa_per_ml
            v_out[past] = self.v_max_ml + (p[past] - p_end) / slope
            k_out[past] = slope
        table = inside & ~past
        if np.any(table):
            v_out[table], k_out[table] = self._invert_on_samples(b, p[table])
        if np.ndim(p_kpa) == 0:
            return v_out[0], k_out[0]
        return v_out, k_out

    def _invert_on_samples(self, b: Branch, p: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Solve p(v) = p on the sampled part of branch ``b`` (vectorised)."""
        samples = self.p_kpa[b.first : b.last + 1]
        ascending = samples if b.rising else samples[::-1]
        position = np.searchsorted(ascending, p, side="right") - 1
        position = np.clip(position, 0, b.last - b.first - 1)
        interval = b.first + position if b.rising else b.last - 1 - position
        pieces = self.pieces
        coef = pieces.p_coefficients[:, interval]
        x0 = pieces.x[interval]
        h = pieces.x[interval + 1] - x0
        rhs = p - coef[3]
        lo = np.zeros_like(h)
        hi = h.copy()
        dp_sample = self.p_kpa[interval + 1] - self.p_kpa[interval]
        with np.errstate(divide="ignore", invalid="ignore"):
            t = np.where(dp_sample != 0, (p - self.p_kpa[interval]) / dp_sample * h, 0.5 * h)
        t = np.clip(t, 0.0, h)
        sign = 1.0 if b.rising else -1.0
        for _ in range(100):
            f = ((coef[0] * t + coef[1]) * t + coef[2]) * t - rhs
            too_far = sign * f > 0
            hi = np.where(too_far, t, hi)
            lo = np.where(too_far, lo, t)
            d = (3 * coef[0] * t + 2 * coef[1]) * t + coef[2]
            with np.errstate(divide="ignore", invalid="ignore"):
                step = np.where(d != 0, t - f / d, np.nan)
            newton_ok = np.isfinite(step) & (step > lo) & (step < hi)
            t_new = np.where(newton_ok, step, 0.5 * (lo + hi))
            done = (np.abs(t_new - t) <= 1e-13 * h) | (f == 0)
            t = np.where(f == 0, t, t_new)
            if np.all(done):
                break
        slope = (3 * coef[0] * t + 2 * coef[1]) * t + coef[2]
        # at an extremum the slope is 0 up to rounding: keep the branch's sign
        slope = np.maximum(slope, 0.0) if b.rising else np.minimum(slope, 0.0)
        return x0 + t, slope

    def volumes_at_pressure(self, p_kpa) -> tuple[np.ndarray, np.ndarray]:
        """All volumes with pressure ``p_kpa``, one column per branch (NaN where a branch
        does not reach that pressure), and the slopes there: the paper's Fig. S5A."""
        p = np.atleast_1d(np.asarray(p_kpa, dtype=float))
        pairs = [self.volume_on_branch(b.index, p) for b in self.branches]
        return np.stack([v for v, _ in pairs], axis=-1), np.stack([k for _, k in pairs], axis=-1)
