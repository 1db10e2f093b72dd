"""Generated segment curves for the path solver's stress tests: knots through PCHIP, and
hypothesis strategies for curves with plateaus, near-zero slopes, peaks and dips."""

import numpy as np
from hypothesis import HealthCheck, settings
from hypothesis import strategies as st
from scipy.interpolate import PchipInterpolator

from labrig.model.segments.curve import SegmentCurve

STRESS = settings(
    max_examples=50,
    deadline=None,
    derandomize=True,  # the same examples on every run: CI must not flake
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large],
)


def knot_curve(name, v_knots, p_knots, *, scale=1.0, samples=240):
    """PCHIP through the knots, sampled on a grid containing them: monotone between
    knots, so every extremum (and every plateau) is exactly where the knots put it."""
    v_knots = np.asarray(v_knots, dtype=float)
    grid = np.union1d(np.linspace(0.0, v_knots[-1], samples), v_knots)
    p = PchipInterpolator(v_knots, p_knots)(grid)
    length_mm = 40.0 + 12.0 * np.sin(grid / v_knots[-1] * 2.0)
    return SegmentCurve(name, grid * scale, p, length_mm, V0_ml=3.0 * scale)


@st.composite
def shapes(draw, peak_kpa=None, min_peaks=0, min_dip_kpa=0.0, min_valley_kpa=0.01):
    """Knots of a curve: a rise (maybe with a plateau or a near-zero slope on it), zero
    to two peaks each followed by a dip, then a stiffening rise to 300 kPa. ``peak_kpa``
    fixes the first peak's pressure."""
    dips = [d for d in (1e-6, 1e-3, 0.05, 0.5, 3.0, 10.0, 25.0) if d >= min_dip_kpa]
    v, p = [0.0], [0.0]

    def step(width_lo=0.5, width_hi=6.0):
        return v[-1] + draw(st.floats(width_lo, width_hi))

    if draw(st.booleans()):  # a plateau or a near-zero slope on the first rise
        level = draw(st.floats(2.0, 15.0))
        v.append(step())
        p.append(level)
        v.append(step(0.2, 3.0))
        p.append(level + draw(st.sampled_from([0.0, 1e-12, 1e-9, 1e-6, 1e-3])))
    n_peaks = draw(st.integers(min_peaks, 2))
    for k in range(n_peaks):
        fixed = k == 0 and peak_kpa is not None
        peak = peak_kpa if fixed else p[-1] + draw(st.floats(1.0, 60.0))
        v.append(step())
        p.append(peak)
        dip = draw(st.sampled_from(dips))
        v.append(step())
        p.append(max(peak - dip, min_valley_kpa))
    v.append(step(3.0, 10.0))
    p.append(max(300.0, p[-1] + 50.0))
    return v, p


# identical segments whose fold mirrors itself (hypothesis found it: a solver failure once)
TWIN = (
    [0.0, 5.967641627768359, 7.796626353723407, 9.349136562795096, 13.8062773266, 23.2763256],
    [0.0, 3.790053089456358, 3.7900540894563584, 46.11880729352488, 46.118806293524884, 300.0],
)
