"""Transitions in measurements: the detector's parts against independent computations,
and the whole detector against the simulated plant's own snap-throughs."""

import numpy as np
import pytest

from labrig.analysis.runfile import load_run
from labrig.analysis.transitions import (
    AgreedTransition,
    MeasuredTransition,
    agreed_transitions,
    bump_excess,
    detect_transitions,
    local_lines,
)


def test_local_lines_match_polyfit_on_each_window():
    rng = np.random.default_rng(1)
    t = np.sort(rng.uniform(0, 10, 2000)) + 1000.0  # far from 0: the sums must stay exact
    y = np.sin(t) + rng.normal(0, 0.1, len(t))
    t_eval = np.array([1001.0, 1003.3, 1007.9])
    value, slope = local_lines(t, y, t_eval, 0.4)
    for k, te in enumerate(t_eval):
        inside = np.abs(t - te) <= 0.4
        fit_slope, fit_value = np.polyfit(t[inside] - te, y[inside], 1)
        assert slope[k] == pytest.approx(fit_slope, rel=1e-8)
        assert value[k] == pytest.approx(fit_value, rel=1e-8)


def test_local_lines_are_nan_without_two_samples():
    value, slope = local_lines(np.array([0.0, 5.0]), np.array([1.0, 2.0]), np.array([2.5]), 1.0)
    assert np.isnan(value[0]) and np.isnan(slope[0])


def test_a_bump_stands_out_but_ramps_kinks_and_bends_do_not():
    x = np.arange(400, dtype=float)
    gap, span = 10, 40
    bump = np.where(np.abs(x - 200) <= 5, 4.0, 0.0)
    excess = bump_excess(bump, gap, span)
    assert np.nanmax(excess) == pytest.approx(4.0)
    assert int(np.nanargmax(excess)) in range(195, 206)
    dip = bump_excess(-bump, gap, span)
    assert np.nanmax(dip) == pytest.approx(4.0)  # a bump downwards is one too
    # a ramp into a kink (the braids touching), a step, a convex wall: no excess
    for smooth in (
        np.where(x < 200, x / 50.0, -0.5),
        np.where(x < 200, 0.0, 3.0),
        np.exp(x / 60.0),
    ):
        assert np.nanmax(bump_excess(smooth, gap, span)) < 0.1
    # no trend on one side: undecided, not a transition
    assert np.all(np.isnan(excess[: gap + 1])) and np.all(np.isnan(excess[-gap - 1 :]))


def _transition(rep, direction, v, dp=-1.0, dl=0.5):
    return MeasuredTransition(rep, direction, 0.0, v, v, v, dp, dl, True, True)


def test_agreement_across_repetitions_by_hand():
    found = [
        _transition(1, 1, 30.0),  # repetition 1 is not averaged
        _transition(2, 1, 16.0, dp=-1.0),
        _transition(3, 1, 16.4, dp=-2.0),
        _transition(4, 1, 16.2, dp=-3.0),
        _transition(3, 1, 25.0),
        _transition(4, -1, 16.1, dp=1.0, dl=np.nan),
    ]
    agreed = agreed_transitions(found, [2, 3, 4], cluster_ml=1.0)
    assert agreed == [
        AgreedTransition(1, 16.2, pytest.approx(0.2), -2.0, 0.5, 3, 3),
        AgreedTransition(1, 25.0, 0.0, -1.0, 0.5, 1, 3),
        AgreedTransition(-1, 16.1, 0.0, 1.0, pytest.approx(np.nan, nan_ok=True), 1, 3),
    ]


def _detect(run):
    record = load_run(run.path)
    found = []
    for rep in record.repetitions:
        length = rep.length
        found += detect_transitions(
            rep.index,
            rep.pressure.time_s,
            rep.pressure.fields["value"],
            rep.pump.time_s,
            rep.pump.fields["value"],
            length.time_s,
            length.fields["value"],
        )
    return found


@pytest.mark.parametrize("fixture", ["snap_run", "library_run"])
def test_every_snap_of_the_plant_is_found_within_0_2_ml_and_nothing_else(fixture, request):
    run = request.getfixturevalue(fixture)
    found = _detect(run)
    assert run.snaps, "the plant must snap in this run"
    matched = []
    for snap in run.snaps:
        near = [
            t
            for t in found
            if t.repetition == snap.repetition and t.direction == snap.direction
            and abs(t.v_ml - snap.v_ml) < 1.0
        ]  # fmt: skip
        assert len(near) == 1, f"{snap} -> {near}"
        assert near[0].v_ml == pytest.approx(snap.v_ml, abs=0.2)
        matched.append(near[0])
    assert len(found) == len(matched)  # no transition the plant did not make


def test_the_fig2_pair_snaps_with_a_pressure_drop(snap_run):
    found = _detect(snap_run)
    assert {t.direction for t in found} == {1}
    for t in found:
        assert t.by_pressure
        assert t.dp_kpa < -0.5  # a drop the size of several noise deviations


def test_a_single_segment_under_volume_control_never_snaps(segment_run):
    """Past its peak and valley a lone segment stays on its curve: no transition."""
    assert _detect(segment_run) == []
