"""Transitions counted as the paper counts them: a peak crossing and the snap it sets off
at the same supplied volume are one transition."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from labrig.model.actuator import (
    SAME_VOLUME_ML,
    Actuator,
    group_paper_transitions,
    paper_transitions,
    quasi_static_path,
)
from labrig.model.actuator.paper_counting import EVENT_FIELDS
from labrig.model.actuator.transitions import transitions
from labrig.model.segments.catalog import analytical_segment

SUMMED = ("dE", "dv", "dl", "dp")


def events(*rows) -> dict[str, np.ndarray]:
    """Columns from rows (direction, v_ml, alpha, beta, stable, dE, dv, dl, dp)."""
    return {name: np.array([row[k] for row in rows]) for k, name in enumerate(EVENT_FIELDS)}


CROSSING_01 = (1, 7.47, 0, 1, True, 1.7e-5, 1.3e-5, 1.1e-6, -1.7e-9)
SNAP_11 = (1, 7.52, 1, 1, False, -0.0343, 0.234, -0.00095, -0.434)


def test_a_crossing_and_the_snap_it_sets_off_are_one_unstable_transition():
    grouped = group_paper_transitions(events(CROSSING_01, SNAP_11))
    assert grouped["v_ml"].tolist() == [7.47]  # the volume before the whole event
    assert (grouped["alpha"][0], grouped["beta"][0]) == (0, 1)
    assert grouped["stable"].tolist() == [False]
    assert grouped["events"].tolist() == [2] and grouped["first"].tolist() == [0]
    for k, name in enumerate(SUMMED, start=5):
        assert grouped[name][0] == pytest.approx(CROSSING_01[k] + SNAP_11[k], rel=1e-15)


def test_a_crossing_alone_stays_stable_and_two_crossings_stay_two():
    second = (1, 7.6, 1, 2, True, 6e-6, 4e-6, 1e-6, -2e-9)
    grouped = group_paper_transitions(events(CROSSING_01, second))
    assert grouped["stable"].tolist() == [True, True]
    assert list(zip(grouped["alpha"], grouped["beta"], strict=True)) == [(0, 1), (1, 2)]
    assert grouped["events"].tolist() == [1, 1]


def test_a_snap_far_past_the_crossing_is_a_transition_of_its_own():
    late = (1, 7.47 + SAME_VOLUME_ML + 0.1, 1, 1, False, -0.03, 0.2, 0.0, -0.4)
    grouped = group_paper_transitions(events(CROSSING_01, late))
    assert grouped["stable"].tolist() == [True, False]
    # nearer than the tolerance it joins
    grouped = group_paper_transitions(events(CROSSING_01, late), same_volume_ml=2.0)
    assert grouped["stable"].tolist() == [False]


def test_snaps_chain_but_never_across_actuators_or_directions():
    chained = (1, 7.9, 1, 2, False, -0.06, 0.5, 0.0, 0.7)
    grouped = group_paper_transitions(events(CROSSING_01, SNAP_11, chained))
    assert grouped["events"].tolist() == [3]
    assert (grouped["alpha"][0], grouped["beta"][0]) == (0, 2)
    other = group_paper_transitions(
        events(CROSSING_01, SNAP_11, chained), actuator=np.array([4, 4, 5])
    )
    assert other["events"].tolist() == [2, 1] and other["actuator"].tolist() == [4, 5]
    back = (-1, 7.9, 2, 1, False, -0.06, 0.5, 0.0, 0.7)
    assert group_paper_transitions(events(CROSSING_01, back))["events"].tolist() == [1, 1]


def test_no_events_no_transitions():
    grouped = group_paper_transitions(events())
    assert all(len(grouped[name]) == 0 for name in (*EVENT_FIELDS, "first", "events"))
    assert paper_transitions([]) == []


event_rows = st.lists(
    st.tuples(
        st.sampled_from([1, -1]),
        st.floats(0.0, 40.0),
        st.integers(0, 3),
        st.integers(0, 3),
        st.booleans(),
        *(st.floats(-1.0, 1.0) for _ in SUMMED),
    ),
    max_size=30,
)


@settings(max_examples=200, deadline=None)
@given(event_rows, st.lists(st.integers(0, 3), min_size=30, max_size=30))
def test_grouping_keeps_the_sums_and_every_event_once(rows, actuator_ids):
    columns = events(*rows)
    actuator = np.sort(np.array(actuator_ids[: len(rows)], dtype=int))
    copies = {name: values.copy() for name, values in columns.items()}
    grouped = group_paper_transitions(columns, actuator)
    for name, values in columns.items():  # pure: the input is untouched
        np.testing.assert_array_equal(values, copies[name])
    # every event in exactly one transition, in order
    assert grouped["events"].sum() == len(rows)
    assert np.all(np.diff(grouped["first"]) == grouped["events"][:-1])
    for name in SUMMED:
        assert math.fsum(grouped[name]) == pytest.approx(math.fsum(columns[name]), abs=1e-9)
    for k, (start, size) in enumerate(zip(grouped["first"], grouped["events"], strict=True)):
        members = range(start, start + size)
        # a transition is made of one event and the snaps after it, at one volume
        assert all(not columns["stable"][i] for i in members[1:])
        assert all(
            abs(columns["v_ml"][i] - columns["v_ml"][i - 1]) <= SAME_VOLUME_ML
            and columns["direction"][i] == columns["direction"][start]
            and actuator[i] == actuator[start]
            for i in members[1:]
        )
        assert grouped["stable"][k] == all(columns["stable"][i] for i in members)
        assert grouped["alpha"][k] == columns["alpha"][start]
        assert grouped["beta"][k] == columns["beta"][start + size - 1]
    # and no transition could have taken the next one's first event
    for start in grouped["first"][1:]:
        assert (
            columns["stable"][start]
            or abs(columns["v_ml"][start] - columns["v_ml"][start - 1]) > SAME_VOLUME_ML
            or columns["direction"][start] != columns["direction"][start - 1]
            or actuator[start] != actuator[start - 1]
        )


def _right_of_peak(actuator: Actuator, v_i_ml) -> int:
    """Segments right of their pressure peak, from their tables: the peak is the first
    sample whose pressure is not exceeded by the next one."""
    count = 0
    for segment, v in zip(actuator.segments, v_i_ml, strict=True):
        p = np.asarray(segment.p_kpa)
        falls = np.flatnonzero(np.diff(p) < 0)
        count += bool(len(falls)) and v > segment.v_ml[falls[0]]
    return count


def test_a_real_pair_counts_the_crossing_and_its_snap_as_one():
    """SI-B44-T20 + SI-B44-T30: the second segment crosses its peak at 13.8 mL and the
    first snaps back over its own 0.19 mL later; the paper calls that one unstable
    (1, 1), both segments crossing their peaks, one inflating and one deflating."""
    actuator = Actuator([analytical_segment(n) for n in ("SI-B44-T20", "SI-B44-T30")])
    found = transitions(quasi_static_path(actuator))
    counted = paper_transitions(found)
    joined = [t for t in counted if len(t.events) > 1]
    assert len(joined) == 1
    t = joined[0]
    crossing, snap = t.events
    assert crossing.stable and not snap.stable
    assert 0 < snap.v_ml - crossing.v_ml < SAME_VOLUME_ML
    assert not t.stable and t.v_ml == crossing.v_ml
    # alpha and beta from the states on either side, read off the segments' tables
    assert t.alpha == _right_of_peak(actuator, crossing.pre.v_i_ml) == 1
    assert t.beta == _right_of_peak(actuator, snap.post.v_i_ml) == 1
    # the volume moved: the snap sends fluid from one segment to the other
    assert t.dv == pytest.approx(crossing.dv + snap.dv) and t.dv > 0.2
    # the energy released, against the segments' energies at the snap's two states
    e_pre, e_post = (actuator.energy_mj(s.v_i_ml) for s in (snap.pre, snap.post))
    assert t.dE - crossing.dE == pytest.approx((e_post - e_pre) / e_pre, rel=1e-9)
    assert t.dE < 0
    # every other transition is one event, and all events are counted once
    assert sum(len(x.events) for x in counted) == len(found) == len(counted) + 1
