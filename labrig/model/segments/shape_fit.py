"""Least-squares fit of noisy pressure samples to a segment's rise-fall-rise shape.

Raw measured p(v) has thousands of samples whose noise (a few tenths of a kPa) is larger
than the change of the softening branch over a millilitre: every local extremum of the
raw data is spurious except the pressure peak and the valley, and a path through them
would snap at each. So
the samples are first averaged on a volume grid (a trimmed mean per bin: robust to
spikes, unbiased for symmetric noise, and it dithers the sensor's quantisation), then
fitted by the best monotone-up, monotone-down, monotone-up sequence in the least-squares
sense: isotonic regression per branch (pool-adjacent-violators) with the two breakpoints
chosen to minimise the total squared error over all pairs. The peak is then by
construction the main maximum before the valley. If the fitted dip is not larger than
the noise, the curve is fitted as one rising branch instead: a dip the data cannot
resolve is not reported.

This module only fits numbers; reading files and building the ``SegmentCurve`` is
``labrig.model.segments.measured``'s job.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

TRIM_FRACTION = 0.1  # of each bin's samples dropped at either end before averaging
DIP_NOISE_FACTOR = 4.0  # a fitted dip must exceed this many standard errors of a bin


def binned_trimmed_means(v, columns, n_bins: int):
    """Average the samples on ``n_bins`` equal volume bins: returns the bins' mean
    volume, the trimmed means of each column and the sample counts (empty bins are
    dropped)."""
    v = np.asarray(v, dtype=float)
    edges = np.linspace(v[0], v[-1], n_bins + 1)
    index = np.clip(np.searchsorted(edges, v, side="right") - 1, 0, n_bins - 1)
    counts = np.bincount(index, minlength=n_bins)
    used = counts > 0
    starts = np.concatenate([[0], np.cumsum(counts)[:-1]])
    trim = np.floor(TRIM_FRACTION * counts).astype(int)

    def trimmed_mean(values):
        order = np.lexsort((values, index))  # by bin, then by value within the bin
        rank = np.arange(len(values)) - starts[index[order]]
        count = counts[index[order]]
        keep = (rank >= trim[index[order]]) & (rank < count - trim[index[order]])
        sums = np.bincount(index[order][keep], weights=values[order][keep], minlength=n_bins)
        kept = np.bincount(index[order][keep], minlength=n_bins)
        return sums[used] / kept[used]

    v_mean = np.bincount(index, weights=v, minlength=n_bins)[used] / counts[used]
    return v_mean, [trimmed_mean(np.asarray(c, dtype=float)) for c in columns], counts[used]


def noise_of_means(y) -> float:
    """Standard deviation of the noise of a sequence with a smooth trend, from the
    median absolute second difference (white noise: var(second difference) = 6 sigma^2)."""
    second = np.diff(np.asarray(y, dtype=float), 2)
    return float(1.4826 * np.median(np.abs(second)) / np.sqrt(6)) if len(second) else 0.0


def isotonic_blocks(y, w, increasing: bool = True):
    """Weighted isotonic regression by pool-adjacent-violators. Returns the blocks as
    (first index, one past the last index, fitted value), in order."""
    sign = 1.0 if increasing else -1.0
    blocks: list[list[float]] = []  # [first, end, weight, weighted sum]
    for k, (yk, wk) in enumerate(zip(y, w, strict=True)):
        block = [k, k + 1, wk, wk * yk]
        while blocks and sign * blocks[-1][3] / blocks[-1][2] >= sign * block[3] / block[2]:
            prev = blocks.pop()
            block = [prev[0], block[1], prev[2] + block[2], prev[3] + block[3]]
        blocks.append(block)
    return [(int(b[0]), int(b[1]), b[3] / b[2]) for b in blocks]


def prefix_isotonic_sse(
    y, w, increasing: bool = True, *, offset: float = 0.0, stop_at: float = np.inf
) -> np.ndarray:
    """sse[k] = weighted squared error of the best monotone fit to y[:k], for every k,
    in one pass (pool-adjacent-violators is online: a new sample only merges blocks at
    the end).

    sse[k] never falls as k grows, so a caller after the least ``offset + sse[k] + c``
    (c >= 0) over k, that already has one of ``stop_at``, need not look past the first
    k where ``offset + sse[k]`` reaches it: those entries are left at infinity."""
    sign = 1.0 if increasing else -1.0
    sse = np.full(len(y) + 1, np.inf)
    sse[0] = 0.0
    weights: list[float] = []
    sums: list[float] = []
    squares: list[float] = []
    total = 0.0
    for k, (yk, wk) in enumerate(zip(y, w, strict=True)):
        wb, sb, qb = wk, wk * yk, wk * yk * yk
        while weights and sign * sums[-1] / weights[-1] >= sign * sb / wb:
            pw, ps, pq = weights.pop(), sums.pop(), squares.pop()
            total -= pq - ps * ps / pw
            wb, sb, qb = wb + pw, sb + ps, qb + pq
        weights.append(wb)
        sums.append(sb)
        squares.append(qb)
        total += qb - sb * sb / wb
        if offset + total >= stop_at:
            break
        sse[k + 1] = total
    return sse


@dataclass(frozen=True)
class ShapeFit:
    """The fitted branches as isotonic blocks: ``branches`` holds one (rising) or three
    (rising, falling, rising) lists of (first, end, value); ``dip_kpa`` is the fitted
    peak minus valley (0 for one branch); ``noise_kpa`` the estimated noise of a mean."""

    branches: list[list[tuple[int, int, float]]]
    dip_kpa: float
    noise_kpa: float


def monotone_pieces(y) -> int:
    """How many monotone runs the sequence y makes (1 for monotone, 3 for
    rise-fall-rise); a flat step counts as a run of its own."""
    signs = np.sign(np.diff(np.asarray(y, dtype=float)))
    if np.any(signs == 0):
        return len(signs) + 1
    return 1 + int(np.count_nonzero(signs[1:] != signs[:-1]))


def residuals_are_noise(residual, sigma) -> bool:
    """The discrepancy principle: chi^2 of the residuals (``sigma`` their standard
    errors) within two of its standard deviations of the number of points."""
    n = len(residual)
    chi2 = float(np.sum((np.asarray(residual) / np.asarray(sigma)) ** 2))
    return chi2 <= n + 2.0 * np.sqrt(2.0 * n)


def smooth_with_shape(x, y, w, pieces: int, *, sigma=None):
    """The smoothest cubic smoothing spline through (x, y, w) that the noise allows and
    whose values at x have the wanted number of monotone ``pieces`` (1: rising; 2:
    rise-fall). Returns the spline (callable, continued past the ends along its end
    pieces), or None if no smoothing gives that shape.

    With ``sigma`` (the standard error of each y) the smoothing is the largest whose
    residuals are still noise (the discrepancy principle: chi^2 within two of its
    standard deviations of the number of points), because what an
    actuator's folds depend on are the curve's slopes, and the smoothing that is best
    for the values (cross-validation) leaves slopes that flicker by more than the
    slope of a falling branch. Without ``sigma``, the spline chosen by generalised
    cross-validation, smoothed further only as far as the shape needs."""
    from scipy.interpolate import make_smoothing_spline

    x = np.asarray(x, dtype=float)
    y = np.asarray(y, dtype=float)
    w = np.asarray(w, dtype=float)
    if len(x) < 5:
        return None
    # the penalty's natural scale: a bin's weight times the cube of the bin width
    scale = float(np.mean(w)) * float(np.mean(np.diff(x))) ** 3

    def shaped(spline) -> bool:
        values = spline(x)
        return monotone_pieces(values) == pieces and values[-1] > values[0]

    if sigma is None:
        for k in range(-1, 12):
            spline = make_smoothing_spline(x, y, w=w, lam=None if k < 0 else scale * 10.0**k)
            if shaped(spline):
                return spline
        return None
    best = least = None
    for k in np.arange(-4.0, 12.01, 0.5):
        spline = make_smoothing_spline(x, y, w=w, lam=scale * 10.0**k)
        if not shaped(spline):
            continue
        if residuals_are_noise(y - spline(x), sigma):
            best = spline
        elif best is None and least is None:
            # shaped only past what the noise allows (a flat end of a branch): the least
            # smoothing that gives the shape (the caller keeps the means where steep)
            least = spline
        else:
            break
    return best if best is not None else least


def fit_rise_fall_rise(
    y, w, *, min_dip_kpa: float = 0.0, noise_kpa: float | None = None
) -> ShapeFit:
    """Best least-squares rise-fall-rise fit of the sequence y (weights w), or a single
    rise if its dip is within the noise of the means (``noise_kpa``, estimated from y
    when not given) or not above ``min_dip_kpa`` (the table's own resolution: a dip of
    a few quantisation steps is rounding)."""
    y = np.asarray(y, dtype=float)
    w = np.asarray(w, dtype=float)
    n = len(y)
    noise = noise_of_means(y) if noise_kpa is None else noise_kpa
    rising = prefix_isotonic_sse(y, w, increasing=True)
    # suffix_rising[j]: best rising fit of y[j:], computed as a falling fit of the reverse
    suffix_rising = prefix_isotonic_sse(y[::-1], w[::-1], increasing=False)[::-1]
    best = (np.inf, 0, 0)
    for i in range(1, n - 1):  # rising y[:i], falling y[i:j], rising y[j:]
        if rising[i] >= best[0]:
            break  # the rising fit alone costs more from here on (it never falls with i)
        falling = prefix_isotonic_sse(
            y[i:], w[i:], increasing=False, offset=rising[i], stop_at=best[0]
        )[1 : n - i]
        total = rising[i] + falling + suffix_rising[i + 1 : n]
        j = int(np.argmin(total))
        if total[j] < best[0]:
            best = (float(total[j]), i, i + 1 + j)
    _, i, j = best
    if n >= 3 and i > 0:
        branches = [
            isotonic_blocks(y[:i], w[:i], increasing=True),
            isotonic_blocks(y[i:j], w[i:j], increasing=False),
            isotonic_blocks(y[j:], w[j:], increasing=True),
        ]
        branches[1] = [(a + i, b + i, value) for a, b, value in branches[1]]
        branches[2] = [(a + j, b + j, value) for a, b, value in branches[2]]
        peak = max(branches[0][-1][2], branches[1][0][2])
        valley = min(branches[1][-1][2], branches[2][0][2])
        if peak - valley > max(DIP_NOISE_FACTOR * noise, min_dip_kpa):
            return ShapeFit(branches, peak - valley, noise)
    return ShapeFit([isotonic_blocks(y, w, increasing=True)], 0.0, noise)


def curvature_constrained_rise(x, y, w, lowest_slope_at: int):
    """The weighted least-squares rising fit of (x, y) whose slope falls up to the
    interval ``lowest_slope_at`` and rises after it: concave up to there, convex after
    (``lowest_slope_at`` = len(x) - 2: concave all along, as a segment's first branch up
    to its peak; 0: convex, as the branch after its valley). Returns the fitted values at
    x. Least squares under these constraints (no smoothing penalty): the slope of the
    fit has one minimum, so noise cannot make it flicker (a rising slope that dips to a
    falling branch's, -0.4 kPa/mL, is a fold pair no clean curve has), and a stiff
    start is followed without the rounding a smoothing penalty gives it.

    Slopes s_k on the intervals are s_min plus non-negative increments away from the
    lowest one; values are y_0 plus the integral of the slopes: a bounded linear least
    squares problem, the free y_0 eliminated by centring (weighted means), the rest
    non-negative least squares (``scipy.optimize.nnls``)."""
    from scipy.optimize import nnls

    x = np.asarray(x, dtype=float)
    y = np.asarray(y, dtype=float)
    w = np.asarray(w, dtype=float)
    n = len(x)
    m = int(np.clip(lowest_slope_at, 0, n - 2))
    k = np.arange(n - 1)
    slopes = np.zeros((n - 1, n - 1))
    slopes[:, 0] = 1.0  # s_min
    # increment j (< m) raises every slope left of it; increment j (>= m) every one right
    slopes[:, 1 : m + 1] = k[:, None] <= np.arange(m)[None, :]
    slopes[:, m + 1 :] = k[:, None] >= np.arange(m, n - 2)[None, :] + 1
    design = (np.tril(np.ones((n, n - 1)), -1) * np.diff(x)[None, :]) @ slopes
    mean_design = w @ design / w.sum()
    mean_y = float(w @ y / w.sum())
    root_w = np.sqrt(w)
    z, _ = nnls((design - mean_design) * root_w[:, None], (y - mean_y) * root_w, maxiter=50 * n)
    return mean_y + (design - mean_design) @ z


def one_minimum_slope_rise(x, y, sigma, *, concave: bool, convex: bool):
    """The rising fit of slope with one minimum (``curvature_constrained_rise``) to
    (x, y) with standard errors ``sigma``: concave all along (a first branch up to its
    peak), convex (the branch after a valley) or, both False, concave up to where the
    data's slope is lowest and convex after (a segment with no peak: its braids' contact
    stiffens it). Returns the fitted values, or None if their residuals are more than
    noise (``residuals_are_noise``): the data then resolve a slope with more extrema.
    Without a peak the lowest slope is searched near that of the bins' moving average
    (the fit is cheap where the constraint is nearly right, slow where far off)."""
    x = np.asarray(x, dtype=float)
    y = np.asarray(y, dtype=float)
    w = 1.0 / np.asarray(sigma, dtype=float) ** 2
    n = len(x)
    if n < 3:
        return None
    if concave or convex:
        candidates = [n - 2 if concave else 0]
    else:
        window = max(3, n // 10)
        smooth = np.convolve(y, np.ones(window) / window, mode="valid")
        centre = int(np.argmin(np.diff(smooth) / np.diff(x)[: len(smooth) - 1])) + window // 2
        candidates = sorted({int(np.clip(centre + d, 0, n - 2)) for d in range(-12, 13, 3)})
    best, best_sse = None, np.inf
    for lowest in candidates:
        values = curvature_constrained_rise(x, y, w, lowest)
        sse = float(w @ (y - values) ** 2)
        if sse < best_sse:
            best, best_sse = values, sse
    return best if residuals_are_noise(y - best, sigma) else None
