"""The comparison with the model: its parts by hand, and simulated runs of library
specimens against the model's own prediction."""

import numpy as np
import pytest

from labrig.analysis import analyse
from labrig.analysis.compare import (
    Comparison,
    PredictedTransition,
    TransitionMatch,
    follows_model,
    match_transitions,
    paper_counted,
    predict,
    rmse,
)
from labrig.analysis.curves import DEFLATE, INFLATE
from labrig.analysis.report import comparison_json
from labrig.analysis.transitions import AgreedTransition
from labrig.model.segments.catalog import analytical_segment


def test_rmse_by_hand_over_the_points_both_have():
    measured = np.array([1.0, 2.0, np.nan, 4.0])
    model = np.array([2.0, 2.0, 3.0, np.nan])
    assert rmse(measured, model) == pytest.approx(np.sqrt((1.0 + 0.0) / 2))
    assert np.isnan(rmse(measured[2:3], model[2:3]))


def _predicted(direction, v, stable=False):
    return PredictedTransition(direction, v, 1, 1, stable, -0.1, 0.2, 0.01, -0.05, -2.0, 1.0)


def _measured(direction, v):
    return AgreedTransition(direction, v, 0.05, -1.9, 1.1, 4, 4)


def test_snaps_pair_with_the_nearest_measurement_of_their_direction():
    predicted = [
        _predicted(INFLATE, 10.0, stable=True),
        _predicted(INFLATE, 19.0),
        _predicted(INFLATE, 22.0),
        _predicted(DEFLATE, 12.0),
    ]
    measured = [
        _measured(INFLATE, 21.5),
        _measured(INFLATE, 19.4),
        _measured(DEFLATE, 19.2),  # wrong direction for the 19 mL snap
        _measured(INFLATE, 30.0),  # predicted nowhere
    ]
    rows = match_transitions(predicted, measured, match_ml=2.0)
    pairs = [
        (r.direction, r.predicted and r.predicted.v_ml, r.measured and r.measured.v_ml)
        for r in rows
    ]
    assert pairs == [
        (INFLATE, 10.0, None),  # stable: listed, never paired
        (INFLATE, 19.0, 19.4),
        (INFLATE, 22.0, 21.5),
        (INFLATE, None, 30.0),
        (DEFLATE, None, 19.2),  # deflation is listed from high volume to low
        (DEFLATE, 12.0, None),
    ]
    assert rows[1].dv_ml == pytest.approx(0.4)
    assert np.isnan(TransitionMatch(INFLATE, None, measured[0]).dv_ml)


def test_the_paper_counts_events_at_one_volume_as_one_snap_paired_once():
    crossing = PredictedTransition(INFLATE, 7.47, 0, 1, True, 2e-5, 1e-5, 1e-6, -1e-9, -1e-7, 0.0)
    snap = PredictedTransition(INFLATE, 7.47, 1, 1, False, -0.03, 0.23, -0.001, -0.43, -30.0, -0.05)
    later = PredictedTransition(INFLATE, 7.52, 1, 2, True, 7e-6, 4e-6, 1e-6, -2e-9, -1e-7, 0.0)
    counted = paper_counted([crossing, snap, later])
    assert [(t.alpha, t.beta, t.stable) for t in counted] == [(0, 1, False), (1, 2, True)]
    one = counted[0]
    assert one.v_ml == 7.47
    # the jumps in kPa and mm add; the relative changes compound
    assert one.dp_kpa == pytest.approx(-30.0 - 1e-7) and one.dl_mm == pytest.approx(-0.05)
    assert one.dE == pytest.approx((1 - 0.03) * (1 + 2e-5) - 1, rel=1e-12)
    assert one.dp == pytest.approx((1 - 0.43) * (1 - 1e-9) - 1, rel=1e-12)
    assert one.dv == pytest.approx(0.23 + 1e-5)
    rows = match_transitions(counted, [_measured(INFLATE, 7.6)], match_ml=2.0)
    assert [(r.predicted.type, r.measured is not None) for r in rows] == [
        ("snap (0,1)", True),
        ("stable (1,2)", False),
    ]
    assert paper_counted([]) == ()


def test_a_steep_stretch_of_the_models_curve_is_told_from_a_transition_it_lacks():
    # the model drops 12 kPa between 9.8 and 10.2 mL (a bulge's drop, stable); a
    # measurement that follows it is on the curve, one that stays flat is not, and a
    # step where the model is smooth is not
    grid = np.linspace(0.0, 20.0, 201)
    model = 50.0 + grid - 12.0 * np.clip((grid - 9.8) / 0.4, 0.0, 1.0)
    comparison = Comparison(None, {INFLATE: model}, {}, {}, {}, (), 2.0)
    step = AgreedTransition(INFLATE, 10.0, 0.02, -11.0, 0.0, 2, 2)
    noise = 0.3 * np.sin(7.0 * grid)
    assert follows_model(comparison, grid, {INFLATE: model + noise}, step)
    flat = 50.0 + grid
    assert not follows_model(comparison, grid, {INFLATE: flat}, step)
    elsewhere = AgreedTransition(INFLATE, 15.0, 0.02, -11.0, 0.0, 2, 2)
    measured_there = model - 11.0 * (grid > 15.0)
    assert not follows_model(comparison, grid, {INFLATE: measured_there}, elsewhere)
    # deflation is looked up on its own phase: none recorded, nothing follows
    back = AgreedTransition(DEFLATE, 10.0, 0.02, 11.0, 0.0, 2, 2)
    nothing = {INFLATE: model, DEFLATE: np.full_like(grid, np.nan)}
    comparison = Comparison(None, {INFLATE: model, DEFLATE: model}, {}, {}, {}, (), 2.0)
    assert not follows_model(comparison, grid, nothing, back)


def test_a_single_segment_is_predicted_by_its_own_curve_both_ways():
    curve = analytical_segment("SI-B46-T20")
    prediction = predict([curve], 10.0, 20.0, deflate=True)
    assert prediction.transitions == ()
    grid = np.linspace(0.0, 20.0, 41)
    for phase in (INFLATE, DEFLATE):
        np.testing.assert_allclose(prediction.on_grid(grid, phase, "p"), curve.pressure_kpa(grid))
        np.testing.assert_allclose(
            prediction.on_grid(grid, phase, "l"), curve.length_mm(grid) + 10.0
        )
    outside = prediction.on_grid(np.array([25.0]), INFLATE, "p")
    assert np.isnan(outside[0])


def test_single_segment_run_against_its_curve(segment_run):
    result = analyse(segment_run.path)
    comparison = result.comparison
    assert comparison.prediction.segments == ("SI-B46-T20",)
    # the plant's sensor sits on the inlet, R Q = 0.33 kPa above the segment while
    # infusing and below it while withdrawing, plus the 0.1 kPa offset left after
    # zeroing: the model cannot know either
    assert comparison.rmse_p_kpa[INFLATE] == pytest.approx(0.43, abs=0.08)
    assert comparison.rmse_p_kpa[DEFLATE] == pytest.approx(0.23, abs=0.08)
    assert comparison.rmse_l_mm[INFLATE] < 0.05
    assert comparison.matches == ()
    assert result.transitions == ()


def test_library_actuator_run_matches_the_model(library_run):
    pytest.importorskip("labrig.model.actuator.path", reason="the actuator path solver")
    result = analyse(library_run.path)
    comparison = result.comparison
    assert comparison.prediction.segments == ("SI-B44-T22", "SI-B50-T20")
    for phase in (INFLATE, DEFLATE):
        assert comparison.rmse_p_kpa[phase] < 0.5
        assert comparison.rmse_l_mm[phase] < 0.5
    snaps = [m for m in comparison.matches if m.predicted is None or not m.predicted.stable]
    assert {m.direction for m in snaps} == {INFLATE, DEFLATE}
    for match in snaps:
        # every predicted snap seen in every averaged repetition, nothing unpredicted
        assert match.predicted is not None and match.measured is not None
        assert match.measured.seen == match.measured.of == 4
        assert abs(match.dv_ml) < 0.6
        assert match.measured.dp_kpa == pytest.approx(match.predicted.dp_kpa, rel=0.15)
        assert match.measured.dl_mm == pytest.approx(match.predicted.dl_mm, abs=0.15)
    # counted as the paper counts, every event is in one transition and the snaps are
    # paired with the same measurements
    counted = [m.predicted for m in comparison.paper_matches if m.predicted is not None]
    assert counted == list(paper_counted(comparison.prediction.transitions))
    paired = {m.measured for m in comparison.paper_matches if m.measured is not None}
    assert paired == {m.measured for m in snaps}
    # compare --json: the events as before, the paper's counting beside them
    doc = comparison_json(result)
    assert list(doc) == ["rmse", "transitions", "paper_transitions", "unpredicted", "energy"]
    assert len(doc["transitions"]) == len(comparison.prediction.transitions)
    assert len(doc["paper_transitions"]) == len(counted)
    assert all(list(t) == list(doc["transitions"][0]) for t in doc["paper_transitions"])
    # unpredicted: the measured transitions that no transition counted so pairs with
    alone = [m.measured for m in comparison.paper_matches if m.predicted is None]
    assert [u["v_meas_ml"] for u in doc["unpredicted"]] == [m.v_ml for m in alone]
