"""Least-squares fit of noisy pressure samples to a segment's rise-fall-rise shape.

Raw measured p(v) has thousands of samples whose noise (a few tenths of a kPa) is larger
than the change of the softening branch over a millilitre: every local extremum of the
raw data is spurious except the pressure peak and the valley (model-notes, trap 10). So
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


def prefix_isotonic_sse(y, w, increasing: bool = True) -> np.ndarray:
    """sse[k] = weighted squared error of the best monotone fit to y[:k], for every k,
    in one pass (pool-adjacent-violators is online: a new sample only merges blocks at
    the end)."""
    sign = 1.0 if increasing else -1.0
    sse = np.zeros(len(y) + 1)
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


def fit_rise_fall_rise(y, w) -> ShapeFit:
    """Best least-squares rise-fall-rise fit of the sequence y (weights w), or a single
    rise if its dip is within the noise."""
    y = np.asarray(y, dtype=float)
    w = np.asarray(w, dtype=float)
    n = len(y)
    noise = noise_of_means(y)
    rising = prefix_isotonic_sse(y, w, increasing=True)
    # suffix_rising[j]: best rising fit of y[j:], computed as a falling fit of the reverse
    suffix_rising = prefix_isotonic_sse(y[::-1], w[::-1], increasing=False)[::-1]
    best = (np.inf, 0, 0)
    for i in range(1, n - 1):  # rising y[:i], falling y[i:j], rising y[j:]
        falling = prefix_isotonic_sse(y[i:], w[i:], increasing=False)[1 : n - i]
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
        if peak - valley > DIP_NOISE_FACTOR * noise:
            return ShapeFit(branches, peak - valley, noise)
    return ShapeFit([isotonic_blocks(y, w, increasing=True)], 0.0, noise)
