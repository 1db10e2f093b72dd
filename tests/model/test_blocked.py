"""The blocked actuator's force against independent computations: Hooke's law for one
segment, the free model's path when the grips are soft, and the energy's gradient."""

import numpy as np
import pytest

from labrig.model.actuator.prediction import predicted_inflation
from labrig.model.blocked import BlockedActuator, axial_stiffness_n_per_mm
from labrig.model.segments.catalog import load_segment


def test_one_segment_pushes_with_its_stiffness_times_its_free_elongation():
    segment = load_segment("SI-B46-T20")
    path = BlockedActuator([segment]).path(20.0, 0.5)
    k = axial_stiffness_n_per_mm(segment)
    # E A / l0 of the paper's latex tube: 1.47 MPa x 31.5 mm^2 over the segment
    assert k == pytest.approx(1.47 * 2 * np.pi * 6.35 * 0.79 / segment.l_mm[0])
    expected = k * (segment.length_mm(path.v_ml) - segment.l_mm[0])
    np.testing.assert_allclose(path.force_n, expected, atol=1e-9)
    assert path.snaps() == []


def test_soft_grips_leave_the_free_path_and_its_snap():
    segments = [load_segment("SI-B48-T30"), load_segment("SI-B50-T20")]
    soft = BlockedActuator(segments, 10.0, stiffness_n_per_mm=[1e-7, 1e-7]).path(26.0, 0.05)
    v, p, _ = predicted_inflation(segments, 26.0, 0.05)
    # the free model snaps at 22.47 mL (labrig model path SI-B48-T30 SI-B50-T20)
    (v_snap, _, _), *_ = soft.snaps()
    assert v_snap == pytest.approx(22.47, abs=0.06)
    before = (soft.v_ml < 22.3) & (soft.v_ml > 0.5)
    np.testing.assert_allclose(soft.p_kpa[before], np.interp(soft.v_ml[before], v, p), atol=0.05)
    assert np.max(np.abs(soft.force_n)) < 1e-4


def test_the_pressure_is_the_energy_gradient_and_segments_share_it():
    actuator = BlockedActuator([load_segment("SI-B48-T30"), load_segment("SI-B50-T20")], 10.0)
    path = actuator.path(20.0, 0.1)
    state = path.v_i_ml[-1]
    g = actuator.gradient_kpa(state)
    assert g[0] == pytest.approx(g[1], abs=1e-5)  # an equilibrium: one pressure
    # central difference of the energy along a volume added to segment 1
    h = 1e-4
    step = np.array([h, 0.0])
    numeric = (actuator.energy_mj(state + step) - actuator.energy_mj(state - step)) / (2 * h)
    assert numeric == pytest.approx(g[0], rel=1e-5)
    # the snap of the blocked pair: the force drops
    ((v_snap, before, after),) = path.snaps()
    assert 15 < v_snap < 17 and after < before
