"""Synthetic segment curves with known extrema for the actuator tests.

``cubic_segment``: p = alpha (v^3 - 1.5 (a + b) v^2 + 3 a b v), whose derivative
3 alpha (v - a)(v - b) puts the peak exactly at a and the valley at b: a rise, a peak, a
fall, a valley and a steep rise, like a braided segment or a Gent balloon.
``kinked_segment``: parabolic arcs with chosen curvatures left and right of the peak,
for the coincident-peak cases where that ratio decides stability.
"""

import numpy as np

from labrig.model.segments.curve import SegmentCurve


def cubic_pressure(v, peak_ml, valley_ml, peak_kpa):
    a, b = peak_ml, valley_ml
    alpha = peak_kpa / (a**2 * (1.5 * b - 0.5 * a))
    return alpha * (v**3 - 1.5 * (a + b) * v**2 + 3 * a * b * v)


def cubic_segment(name, peak_ml, valley_ml, peak_kpa, *, samples=801, l0_mm=40.0):
    v = np.linspace(0.0, 2.2 * valley_ml, samples)
    p = cubic_pressure(v, peak_ml, valley_ml, peak_kpa)
    length = l0_mm + 0.8 * v - 0.02 * v**2
    return SegmentCurve(name, v, p, length, V0_ml=3.0)


def random_cubic(rng, name):
    a = rng.uniform(3.0, 7.0)
    return cubic_segment(name, a, a * rng.uniform(1.6, 2.6), rng.uniform(25.0, 40.0))


def kinked_segment(
    name, peak_ml, peak_kpa, left_curvature, right_curvature, valley_ml, *, samples=1201
):
    """p = P - c_left (v - v0)^2 up to the peak, P - c_right (v - v0)^2 down to the
    valley, then a parabola rising from the valley. P = c_left v0^2 so p(0) = 0."""
    assert np.isclose(left_curvature * peak_ml**2, peak_kpa)
    v = np.linspace(0.0, 2.5 * valley_ml, samples)
    v = np.union1d(v, [peak_ml, valley_ml])
    valley_kpa = peak_kpa - right_curvature * (valley_ml - peak_ml) ** 2
    p = np.where(
        v <= peak_ml,
        peak_kpa - left_curvature * (v - peak_ml) ** 2,
        np.where(
            v <= valley_ml,
            peak_kpa - right_curvature * (v - peak_ml) ** 2,
            valley_kpa + 4.0 * (v - valley_ml) ** 2,
        ),
    )
    return SegmentCurve(name, v, p, 30.0 + 0.5 * v, V0_ml=2.0)
