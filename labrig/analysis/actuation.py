"""Actuation time: how long a quick step's consequences take to happen.

After a reservoir step the specimen's pressure and length move from where they were
before the step to where they settle. The actuation time is the 10-90 % time of that
change (the paper's Movie S7 figure): from the last moment the signal was still within
10 % of its change from the start to the moment it entered, for good, the last 10 % of
the change. Taking the final entry makes it robust to what happens in between: the push
itself surges the pressure, a water line rings, and a length may overshoot.

The levels are medians (a few noisy samples move them little): before, over the
``baseline_s`` ending at the step; after, over the last ``settled_s`` of the window. The
crossings are found on the signal averaged over ``smooth_s``: among thousands of 1 kHz
samples a few noisy ones always stray outside a band that the signal itself has left.
Pure functions over arrays; the run file's reading is ``labrig.analysis.experiments``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class StepResponse:
    """One signal's response to a step: levels, change and the 10-90 % time (NaN when
    the signal did not change beyond its noise)."""

    before: float
    after: float
    t10_s: float
    t90_s: float

    @property
    def change(self) -> float:
        return self.after - self.before

    @property
    def actuation_time_s(self) -> float:
        return self.t90_s - self.t10_s


def step_response(
    t_s: np.ndarray,
    values: np.ndarray,
    t_step_s: float,
    t_end_s: float,
    *,
    baseline_s: float = 0.5,
    settled_s: float = 0.5,
    noise: float = 0.0,
    smooth_s: float = 0.025,
) -> StepResponse:
    """The 10-90 % response of ``values`` to a step at ``t_step_s``, settled by
    ``t_end_s``; ``noise`` is the smallest change believed."""
    t = np.asarray(t_s, dtype=float)
    x = np.asarray(values, dtype=float)
    ok = np.isfinite(x)
    t, x = t[ok], x[ok]
    before_mask = (t >= t_step_s - baseline_s) & (t < t_step_s)
    after_mask = (t > t_end_s - settled_s) & (t <= t_end_s)
    window = (t >= t_step_s) & (t <= t_end_s)
    if not before_mask.any() or not after_mask.any() or window.sum() < 3:
        return StepResponse(np.nan, np.nan, np.nan, np.nan)
    before = float(np.median(x[before_mask]))
    after = float(np.median(x[after_mask]))
    change = after - before
    if not abs(change) > noise:
        return StepResponse(before, after, np.nan, np.nan)
    tw, xw = t[window], x[window]
    width = round(smooth_s / float(np.median(np.diff(tw)))) if len(tw) > 1 else 1
    if width > 1:
        xw = np.convolve(
            np.pad(xw, (width // 2, width - 1 - width // 2), mode="edge"),
            np.ones(width) / width,
            mode="valid",
        )
    fraction = (xw - before) / change
    short = np.flatnonzero(fraction < 0.9)
    i90 = int(short[-1]) + 1 if short.size else 0
    if i90 >= fraction.size:
        return StepResponse(before, after, np.nan, np.nan)
    below = np.flatnonzero(fraction[: i90 + 1] <= 0.1)
    i10 = int(below[-1]) if below.size else 0
    return StepResponse(before, after, float(tw[i10]), float(tw[i90]))
