"""The predicted inflation against direct evaluations: one segment is its own curve, and
an actuator's predicted pressure equals every segment's pressure at the path's state."""

import numpy as np
import pytest

from labrig.model.actuator.prediction import predicted_inflation, predicted_peak_pressure_kpa
from labrig.model.segments.catalog import analytical_segment


def test_single_segment_is_its_curve():
    segment = analytical_segment("B46-T20")
    v, p, length = predicted_inflation([segment], 15.0)
    assert v[0] == 0.0 and v[-1] == pytest.approx(15.0)
    np.testing.assert_allclose(p, segment.pressure_kpa(v))
    np.testing.assert_allclose(length, segment.length_mm(v))
    peak, at = predicted_peak_pressure_kpa([segment], 15.0)
    assert peak == pytest.approx(segment.peak.p_kpa, abs=0.01)
    assert at == pytest.approx(segment.peak.v_ml, abs=0.05)


def test_actuator_peak_is_below_the_largest_segment_peak_before_the_wall():
    a, b = analytical_segment("B48-T30"), analytical_segment("B50-T20")
    v, p, _ = predicted_inflation([a, b], 30.0)
    assert v.max() == pytest.approx(30.0)
    assert np.all(np.diff(v) >= -1e-9)  # inflation only: volume never decreases
    peak, at = predicted_peak_pressure_kpa([a, b], 30.0)
    assert p[0] == 0.0 and p.max() == peak and at == v[np.argmax(p)]
    # before any segment reaches its stiffening wall, the shared pressure can never
    # exceed the highest single-segment peak
    assert peak <= max(a.peak.p_kpa, b.peak.p_kpa) + 1e-6
