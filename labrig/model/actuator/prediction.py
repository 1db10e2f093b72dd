"""What the model predicts for a specimen under a protocol: the quasi-static inflation
curve of one segment or of a combined actuator, as arrays on the supplied volume.

The dry run uses it for the peak pressure a protocol will reach, the analysis for the
model curve a measurement is compared with.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from labrig.model.segments.curve import SegmentCurve


def predicted_inflation(
    segments: Sequence[SegmentCurve], v_max_ml: float, dv_ml: float = 0.05
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(v_ml, p_kpa, l_mm) of the quasi-static inflation from 0 to ``v_max_ml``.

    One segment is its own curve; several follow the actuator's path, snaps included
    (a snap shows as two points at the same volume).
    """
    if len(segments) == 1:
        (segment,) = segments
        v = np.linspace(0.0, v_max_ml, max(2, int(np.ceil(v_max_ml / dv_ml)) + 1))
        return v, segment.pressure_kpa(v), segment.length_mm(v)
    from labrig.model.actuator.equilibria import Actuator
    from labrig.model.actuator.path import quasi_static_path, sample_path

    path = sample_path(quasi_static_path(Actuator(segments), v_max_ml), dv_ml)
    return path.v_ml, path.p_kpa, path.l_mm


def predicted_peak_pressure_kpa(
    segments: Sequence[SegmentCurve], v_max_ml: float
) -> tuple[float, float]:
    """The highest pressure of the inflation up to ``v_max_ml`` and where it occurs."""
    v, p, _ = predicted_inflation(segments, v_max_ml)
    i = int(np.argmax(p))
    return float(p[i]), float(v[i])
