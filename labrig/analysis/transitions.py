"""Snap-through transitions found in a measurement: sudden changes at constant volume.

Under volume control a snap-through moves fluid between the segments at (nearly)
constant supplied volume: over the second or so the flow takes the pressure and the
length jump while the pump moves only a fraction of a millilitre. A quasi-static branch
changes at a rate set by its own slope. So, per pump motion (holds, and the pump's start
and stop, where the inlet's flow-resistance offset steps, are left out):

- steepness: dp/dv and dl/dv in time, from least-squares lines over a short window
  divided by the pump rate (signed by the direction of motion, so it is the slope of
  the curve whichever way it is run);
- trend: on each side of a moment, leaving a gap for the transition itself, the
  steepness the curve had there, both as the median and as a fitted line extrapolated
  to the moment; the excess is how far the steepness stands beyond the trends on both
  sides, the smaller of the two views. A snap is a bump that rises above (or dips below)
  both sides. A curve that bends quickly but smoothly (the stiffening wall, a peak, the
  kink where the braids touch, a ramp into it) passes from one side's trend to the other
  and stays between them, or follows a line that predicts it;
- a candidate is a run of excess above its threshold (extended while above half of
  it), in the pressure or the length or both. The threshold is a floor in kPa/mL
  (mm/mL) or ``noise_factor`` standard deviations of the steepness' noise, whichever is
  larger; that noise follows from the samples' own scatter (second differences), so a
  noisy sensor raises it and a quiet one lets small snaps through;
- a candidate is kept if, during it, the curve stands off the nearer of its trend
  lines before and after by at least half of ``min_dp_kpa`` (or ``min_dl_mm``): a
  curve that only bends lies on one line or the other;
- its time is when the steepness (from a shorter window, for sharpness), rising into
  the bump, crosses half-way from its level before to the bump's extreme
  (constant-fraction timing): the internal flow peaks near that point, while the
  pressure's own fastest change lags it (the segments stiffen as the fluid moves). Its
  volume is the supplied volume then;
- its size dp is the step between the trend lines at that time (the quasi-static
  slope is not counted as jump), or the dip, if deeper: a snap onto a stiff branch
  drops and then recovers while the pump goes on;
- its length change dl is measured on the length series' own jump (``length_jump``):
  at a native camera rate the length jumps within a few frames, while the pressure's
  extent (a spike and its recovery) may span a millilitre, and lines fitted beyond that
  would cross the next kink of the length curve. So dl is the step, at the middle of
  the jump, between lines through the length just before and just after the frames
  where its rate stands out from the rate around it: the quasi-static jump, post minus
  pre at one volume, as the model defines it.

A snap within ``trend_gap_s`` of the start or end of a pump motion has no trend on one
side and is not reported.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np

from labrig.analysis.curves import motion_at, volume_at
from labrig.arrays import nanmedian_rows, runs_of_true


@dataclass(frozen=True)
class DetectionSettings:
    """Thresholds and windows of the detector (stored with every analysis)."""

    step_s: float = 0.05  # resolution of the steepness series
    pressure_window_s: float = 1.0  # least-squares window of dp/dt for detection
    length_window_frames: float = 2.5  # window of dl/dt, in camera frame intervals
    trend_gap_s: float = 1.5  # left out on each side for the transition itself
    trend_s: float = 6.0  # stretch of the trend on each side
    pressure_excess_kpa_per_ml: float = 1.0  # least dp/dv beyond the trends of a snap
    length_excess_mm_per_ml: float = 1.5  # least dl/dv beyond the trends of a snap
    noise_factor: float = 6.0  # and at least this many standard deviations of its noise
    min_dp_kpa: float = 0.5
    min_dl_mm: float = 0.3
    timing_fraction: float = 0.5  # constant-fraction timing of a transition
    timing_window_s: float = 0.5  # least-squares window for a transition's time and size
    step_fit_s: float = 2.0  # lines before/after a transition, for dp
    jump_fit_s: float = 1.0  # lines before/after the length's own jump, for dl
    jump_fraction: float = 0.2  # the length's jump: its rate beyond this part of the peak
    cluster_ml: float = 1.0  # transitions of different repetitions closer than this agree


@dataclass(frozen=True)
class MeasuredTransition:
    """One transition seen in one repetition. ``direction`` +1 on inflation, -1 on
    deflation; ``t_s``, ``v_ml`` its time and supplied volume (constant-fraction
    timing); ``v_start_ml``..``v_end_ml`` its extent; dp, dl its size in kPa and mm (dl
    NaN without a camera); seen in the pressure, the length or both."""

    repetition: int
    direction: int
    t_s: float
    v_ml: float
    v_start_ml: float
    v_end_ml: float
    dp_kpa: float
    dl_mm: float
    by_pressure: bool
    by_length: bool

    @property
    def kind(self) -> str:
        seen = [name for name, flag in (("p", self.by_pressure), ("l", self.by_length)) if flag]
        return "+".join(seen)


def local_lines(
    t: np.ndarray, y: np.ndarray, t_eval: np.ndarray, half_width_s: float
) -> tuple[np.ndarray, np.ndarray]:
    """Value and slope at each ``t_eval`` of the least-squares line through the samples
    within ±half_width_s (NaN where fewer than 2 distinct times fall inside).

    Running sums make this O(n) for any window; times are taken relative to the first
    sample so that the sums stay well-conditioned.
    """
    x = t - t[0]
    xe = t_eval - t[0]
    zero = np.zeros(1)
    c1 = np.concatenate([zero, np.arange(1, len(x) + 1, dtype=float)])
    cx = np.concatenate([zero, np.cumsum(x)])
    cxx = np.concatenate([zero, np.cumsum(x * x)])
    cy = np.concatenate([zero, np.cumsum(y)])
    cxy = np.concatenate([zero, np.cumsum(x * y)])
    lo = np.searchsorted(x, xe - half_width_s, side="left")
    hi = np.searchsorted(x, xe + half_width_s, side="right")
    n = c1[hi] - c1[lo]
    with np.errstate(invalid="ignore", divide="ignore"):
        x_mean = (cx[hi] - cx[lo]) / n
        y_mean = (cy[hi] - cy[lo]) / n
        sxx = (cxx[hi] - cxx[lo]) - n * x_mean**2
        sxy = (cxy[hi] - cxy[lo]) - n * x_mean * y_mean
        ok = (n >= 2) & (sxx > 1e-12 * np.maximum(n, 1) * half_width_s**2)
        slope = np.where(ok, sxy / np.where(ok, sxx, 1.0), np.nan)
        value = np.where(ok, y_mean + slope * (xe - x_mean), np.nan)
    return value, slope


def slope_noise(t: np.ndarray, y: np.ndarray, half_width_s: float) -> float:
    """Standard deviation of a ``local_lines`` slope caused by white noise in y:
    sigma / sqrt(sum (t - mean t)^2) over a window's samples. Sigma comes from the
    second differences of the samples (median absolute deviation: robust, and a smooth
    signal barely moves them)."""
    if len(y) < 4 or np.ptp(t) <= 0:
        return 0.0
    second = np.diff(y, 2)
    sigma = 1.4826 * np.median(np.abs(second - np.median(second))) / np.sqrt(6.0)
    per_window = (len(t) - 1) / np.ptp(t) * 2.0 * half_width_s
    return float(sigma / np.sqrt(max(per_window, 2.0) * (2.0 * half_width_s) ** 2 / 12.0))


def _side_windows(a: np.ndarray, gap: int, span: int) -> tuple[np.ndarray, np.ndarray]:
    """For every i, the ``span`` values of ``a`` ending ``gap`` before i and the ``span``
    values starting ``gap`` after it (NaN beyond the ends), as (n, span) views."""
    padded = np.concatenate([np.full(gap + span, np.nan), a, np.full(gap + span, np.nan)])
    windows = np.lib.stride_tricks.sliding_window_view(padded, span)
    n = len(a)
    after = 2 * gap + span + 1
    return windows[:n], windows[after : after + n]


def _extrapolated(windows: np.ndarray, at: float) -> np.ndarray:
    """The least-squares line through each window (x = 0..span-1, NaN ignored) at x =
    ``at``; NaN for windows less than half full."""
    span = windows.shape[1]
    ok = np.isfinite(windows)
    x = np.where(ok, np.arange(span, dtype=float), 0.0)
    y = np.where(ok, windows, 0.0)
    n = ok.sum(axis=1)
    with np.errstate(invalid="ignore", divide="ignore"):
        x_mean = x.sum(axis=1) / n
        y_mean = y.sum(axis=1) / n
        sxx = (x * x).sum(axis=1) - n * x_mean**2
        sxy = (x * y).sum(axis=1) - n * x_mean * y_mean
        line = y_mean + sxy / sxx * (at - x_mean)
    return np.where(n >= span / 2, line, np.nan)


def _beyond(steepness: np.ndarray, before: np.ndarray, after: np.ndarray) -> np.ndarray:
    """How far above both or below both trends; 0 between them, NaN without both."""
    excess = np.fmax(steepness - np.maximum(before, after), np.minimum(before, after) - steepness)
    return np.where(np.isnan(before) | np.isnan(after), np.nan, np.maximum(excess, 0.0))


def bump_excess(steepness: np.ndarray, gap: int, span: int) -> np.ndarray:
    """The excess of the steepness over the trends on both sides (module docstring):
    the smaller of the excess over the side medians and over the side lines."""
    before, after = _side_windows(steepness, gap, span)
    over_medians = _beyond(steepness, nanmedian_rows(before), nanmedian_rows(after))
    over_lines = _beyond(
        steepness, _extrapolated(before, span + gap), _extrapolated(after, -gap - 1.0)
    )
    return np.fmin(over_medians, over_lines)


def _events(excess: np.ndarray, threshold: float) -> list[tuple[int, int, int]]:
    """(first, last, peak) of each run above ``threshold``, extended while above half."""
    out = []
    for first, last in runs_of_true(np.nan_to_num(excess, nan=-np.inf) > 0.5 * threshold):
        peak = first + int(np.nanargmax(excess[first : last + 1]))
        if excess[peak] > threshold:
            out.append((first, last, peak))
    return out


def _onset_time(
    t: np.ndarray, steepness: np.ndarray, peak: int, gap: int, span: int, fraction: float
) -> tuple[float, float]:
    """Constant-fraction timing: when the steepness, on its way into the bump whose
    excess peaks at ``peak``, first crosses ``fraction`` of the way from its median
    level before the bump to the bump's extreme (linear between samples). Returns that
    time and the bump's sign (+1 above the level before, -1 below)."""
    base = nanmedian_rows(_side_windows(steepness, gap, span)[0][peak : peak + 1])[0]
    if not np.isfinite(base):
        return float(t[peak]), 0.0
    sign = 1.0 if steepness[peak] >= base else -1.0
    rise = sign * (steepness - base)
    # the extreme of the bump itself may lie a little after the excess' peak
    k = peak + int(np.nanargmax(rise[peak : peak + gap + 1]))
    level = fraction * rise[k]
    while k > 0 and rise[k - 1] > level:
        k -= 1
    if k == 0 or not np.isfinite(rise[k - 1]):
        return float(t[k]), sign
    weight = (level - rise[k - 1]) / (rise[k] - rise[k - 1])
    return float(t[k - 1] + weight * (t[k] - t[k - 1])), sign


def _jump(
    t,
    y,
    t_from: float,
    t_to: float,
    t_at: float,
    span_s: float,
    lo: float,
    hi: float,
    inner=None,
    sign: float = 0.0,
) -> tuple[float, float]:
    """(size, significance) of a transition in one series.

    Lines are fitted over ``span_s`` before ``t_from`` and after ``t_to`` (within the
    motion [lo, hi]): the curve's trends on either side. The significance is the largest
    distance of a transition sample ``inner`` (t, y; by default the series' own) from
    the nearer of the two lines: a curve that only bends (a kink) lies on one line or
    the other and scores 0, a step scores half its height, a dip its depth. The size is
    the step between the lines at ``t_at``; with a ``sign`` (the way the transition
    started), the largest departure that way from the trend before, if larger: a snap
    onto a stiff branch dips and then recovers, and its drop is the dip.
    """

    def line(a: float, b: float) -> tuple[float, float]:
        inside = (t >= max(a, lo)) & (t <= min(b, hi))
        if np.count_nonzero(inside) < 2 or np.ptp(t[inside]) <= 0:
            return np.nan, np.nan
        slope, intercept = np.polyfit(t[inside] - t_at, y[inside], 1)
        return float(slope), float(intercept)

    (k_pre, c_pre), (k_post, c_post) = line(t_from - span_s, t_from), line(t_to, t_to + span_s)
    step = c_post - c_pre
    t_in, y_in = inner if inner is not None else (t, y)
    chosen = (t_in >= t_from) & (t_in <= t_to) & np.isfinite(y_in)
    if not np.isfinite(step) or not np.any(chosen):
        return step, abs(step) / 2  # no sample inside (a sparse camera): the step alone
    t_in, y_in = t_in[chosen], y_in[chosen]
    from_pre = y_in - (c_pre + k_pre * (t_in - t_at))
    from_post = y_in - (c_post + k_post * (t_in - t_at))
    significance = float(np.max(np.fmin(np.abs(from_pre), np.abs(from_post))))
    if sign:
        dip = float(np.max(sign * from_pre))
        if dip > sign * step:
            return sign * dip, significance
    return step, significance


def detect_transitions(
    repetition: int,
    pressure_t_s: np.ndarray,
    pressure_kpa: np.ndarray,
    pump_t_s: np.ndarray,
    pump_v_ml: np.ndarray,
    length_t_s: np.ndarray | None = None,
    length_mm: np.ndarray | None = None,
    settings: DetectionSettings | None = None,
) -> list[MeasuredTransition]:
    """The transitions of one repetition (see the module docstring)."""
    s = settings or DetectionSettings()
    if len(pump_t_s) < 2 or len(pressure_t_s) < 2:
        return []
    motions = _motions(pump_t_s, pump_v_ml)
    found: list[MeasuredTransition] = []
    for t_lo, t_hi, direction, rate_ml_s in motions:
        found += _detect_in_motion(
            repetition, direction, rate_ml_s, t_lo, t_hi, pressure_t_s, pressure_kpa,
            pump_t_s, pump_v_ml, length_t_s, length_mm, s,
        )  # fmt: skip
    return found


def _motions(pump_t_s: np.ndarray, pump_v_ml: np.ndarray) -> list[tuple[float, float, int, float]]:
    """(start, end, direction, rate in mL/s) of each stretch of one-way pumping."""
    direction = motion_at(0.5 * (pump_t_s[1:] + pump_t_s[:-1]), pump_t_s, pump_v_ml)
    out = []
    for value in (1, -1):
        for first, last in runs_of_true(direction == value):
            # the pump started and stopped somewhere inside the first and last intervals,
            # and the inlet's flow-resistance offset steps there: keep the readings inside
            t0, t1 = pump_t_s[first + 1], pump_t_s[last]
            moved = abs(pump_v_ml[last] - pump_v_ml[first + 1])
            if t1 > t0 and moved > 0:
                out.append((float(t0), float(t1), value, moved / (t1 - t0)))
    return sorted(out)


def _detect_in_motion(
    repetition, direction, rate_ml_s, t_lo, t_hi, pt, p, pump_t, pump_v, lt, lv, s
) -> list[MeasuredTransition]:
    half_p = 0.5 * s.pressure_window_s
    t_eval = np.arange(t_lo + half_p, t_hi - half_p, s.step_s)
    if len(t_eval) < 3:
        return []
    gap, span = round(s.trend_gap_s / s.step_s), max(1, round(s.trend_s / s.step_s))
    in_motion = (pt >= t_lo) & (pt <= t_hi)
    _, p_rate = local_lines(pt[in_motion], p[in_motion], t_eval, half_p)
    # sharper, for the time and the size of a transition
    sharp_p, sharp_rate = local_lines(pt[in_motion], p[in_motion], t_eval, 0.5 * s.timing_window_s)
    steepness = {"p": direction * p_rate / rate_ml_s}
    excess = {"p": bump_excess(steepness["p"], gap, span)}
    threshold_p = max(
        s.pressure_excess_kpa_per_ml,
        s.noise_factor * slope_noise(pt[in_motion], p[in_motion], half_p) / rate_ml_s,
    )
    events = [(a, b, k, "p") for a, b, k in _events(excess["p"], threshold_p)]

    if lt is not None and len(lt) >= 3:
        in_motion_l = (lt >= t_lo) & (lt <= t_hi)
        frame_s = float(np.median(np.diff(lt)))
        half_l = 0.5 * max(s.pressure_window_s, s.length_window_frames * frame_s)
        if np.count_nonzero(in_motion_l) >= 3:
            _, l_rate = local_lines(lt[in_motion_l], lv[in_motion_l], t_eval, half_l)
            steepness["l"] = direction * l_rate / rate_ml_s
            excess["l"] = bump_excess(steepness["l"], gap, span)
            threshold_l = max(
                s.length_excess_mm_per_ml,
                s.noise_factor * slope_noise(lt[in_motion_l], lv[in_motion_l], half_l) / rate_ml_s,
            )
            events += [(a, b, k, "l") for a, b, k in _events(excess["l"], threshold_l)]

    out = []
    for group in _merge(sorted(events), gap):
        first = min(e[0] for e in group)
        last = max(e[1] for e in group)
        by_p = any(e[3] == "p" for e in group)
        by_l = any(e[3] == "l" for e in group)
        # the pressure (1 kHz) times an event better than the camera
        channel = "p" if by_p else "l"
        peak = max((e[2] for e in group if e[3] == channel), key=lambda k: excess[channel][k])
        timing = steepness[channel] if channel == "l" else direction * sharp_rate / rate_ml_s
        t_peak, bump_sign = _onset_time(t_eval, timing, peak, gap, span, s.timing_fraction)
        t_from, t_to = float(t_eval[first]), float(t_eval[last])
        fit = (t_from, t_to, t_peak, s.step_fit_s, t_lo, t_hi)
        # a steepness bump below the trend is a pressure falling with the supply
        drop_sign = bump_sign * direction if channel == "p" else 0.0
        dp, dp_score = _jump(pt, p, *fit, inner=(t_eval, sharp_p), sign=drop_sign)
        dl = dl_score = np.nan
        if lt is not None and len(lt) >= 2:
            dl, dl_score = _jump(lt, lv, *fit)
            # the size from the length's own jump, where the camera resolves one
            dl = length_jump(lt, lv, t_peak, s, t_lo, t_hi, fallback=dl)
        if not (dp_score >= 0.5 * s.min_dp_kpa or dl_score >= 0.5 * s.min_dl_mm):
            continue
        v_peak, v_from, v_to = volume_at(np.array([t_peak, t_from, t_to]), pump_t, pump_v)
        out.append(
            MeasuredTransition(
                repetition=repetition,
                direction=direction,
                t_s=t_peak,
                v_ml=float(v_peak),
                v_start_ml=float(v_from),
                v_end_ml=float(v_to),
                dp_kpa=float(dp),
                dl_mm=float(dl),
                by_pressure=by_p,
                by_length=by_l,
            )
        )
    return out


def length_jump(
    lt: np.ndarray,
    lv: np.ndarray,
    t_at: float,
    s: DetectionSettings,
    lo: float,
    hi: float,
    fallback: float = np.nan,
) -> float:
    """The length's quasi-static jump at a transition timed ``t_at`` (module docstring).

    Within ``trend_gap_s`` of ``t_at`` the jump is where the length's rate (lines over
    two frame periods) departs most from its median there; it extends while the
    departure stays above ``jump_fraction`` of that. Lines over ``jump_fit_s`` before
    and after it (inside the motion [lo, hi]) are evaluated at its middle. Too few
    frames to see a jump (a slow camera), or a snap so slow that no frame-to-frame rate
    stands out of the noise: ``fallback`` (the step between the transition's trends).
    """
    inside = (lt >= lo) & (lt <= hi) & np.isfinite(lv)
    t, y = lt[inside], lv[inside]
    near = np.nonzero(np.abs(t - t_at) <= s.trend_gap_s)[0]
    if len(near) < 8:
        return fallback
    frame_s = float(np.median(np.diff(t[near])))
    _, rate = local_lines(t, y, t[near], 2.0 * frame_s)
    departure = np.abs(rate - np.nanmedian(rate))
    if not np.any(np.isfinite(departure)):
        return fallback
    peak = int(np.nanargmax(departure))
    if departure[peak] < s.noise_factor * slope_noise(t[near], y[near], 2.0 * frame_s):
        return fallback  # no jump within the frames: a snap slower than trend_gap_s
    level = s.jump_fraction * departure[peak]
    first = last = peak
    while first > 0 and departure[first - 1] > level:
        first -= 1
    while last < len(near) - 1 and departure[last + 1] > level:
        last += 1
    t_a, t_b = t[near[first]], t[near[last]]
    t_mid = 0.5 * (t_a + t_b)
    before = (t >= t_a - s.jump_fit_s) & (t < t_a)
    after = (t > t_b) & (t <= t_b + s.jump_fit_s)
    if np.count_nonzero(before) < 3 or np.count_nonzero(after) < 3:
        return fallback
    pre = np.polyval(np.polyfit(t[before] - t_mid, y[before], 1), 0.0)
    post = np.polyval(np.polyfit(t[after] - t_mid, y[after], 1), 0.0)
    return float(post - pre)


def _merge(events: list, gap: int) -> list[list]:
    """Group events (sorted by start) whose extents overlap or lie within ``gap``."""
    groups: list[list] = []
    for event in events:
        if groups and event[0] <= max(e[1] for e in groups[-1]) + gap:
            groups[-1].append(event)
        else:
            groups.append([event])
    return groups


@dataclass(frozen=True)
class AgreedTransition:
    """A transition seen at about the same volume in several repetitions: mean and
    spread of its volume, mean jump, and in how many of the repetitions it was seen."""

    direction: int
    v_ml: float
    v_std_ml: float
    dp_kpa: float
    dl_mm: float
    seen: int
    of: int


def agreed_transitions(
    transitions: list[MeasuredTransition], repetitions: list[int], cluster_ml: float
) -> list[AgreedTransition]:
    """Group the transitions of ``repetitions`` by direction and volume (members within
    ``cluster_ml`` of their group's first) and summarise each group."""
    chosen = [t for t in transitions if t.repetition in repetitions]
    out = []
    for direction in (1, -1):
        members = sorted((t for t in chosen if t.direction == direction), key=lambda t: t.v_ml)
        groups: list[list[MeasuredTransition]] = []
        for t in members:
            if groups and t.v_ml - groups[-1][0].v_ml <= cluster_ml:
                groups[-1].append(t)
            else:
                groups.append([t])
        for group in groups:
            v = np.array([t.v_ml for t in group])
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", RuntimeWarning)  # all NaN: no camera
                dl = float(np.nanmean([t.dl_mm for t in group]))
            out.append(
                AgreedTransition(
                    direction=direction,
                    v_ml=float(v.mean()),
                    v_std_ml=float(v.std(ddof=1)) if len(v) > 1 else 0.0,
                    dp_kpa=float(np.mean([t.dp_kpa for t in group])),
                    dl_mm=dl,
                    seen=len({t.repetition for t in group}),
                    of=len(repetitions),
                )
            )
    return out
