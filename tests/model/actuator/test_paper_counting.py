"""Transitions counted as the paper counts them: the events at one supplied volume are one
transition, their relative changes compounded."""

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

METRICS = ("dE", "dv", "dl", "dp")
COMPOUNDED = ("dE", "dl", "dp")


def events(*rows) -> dict[str, np.ndarray]:
    """Columns from rows (direction, v_ml, alpha, beta, stable, dE, dv, dl, dp)."""
    return {name: np.array([row[k] for row in rows]) for k, name in enumerate(EVENT_FIELDS)}


CROSSING_01 = (1, 7.47, 0, 1, True, 1.7e-5, 1.3e-5, 1.1e-6, -1.7e-9)
SNAP_11 = (1, 7.52, 1, 1, False, -0.0343, 0.234, -0.00095, -0.434)
# a snap set off at the crossing's own volume, and the snap its landing state sets off
SNAP_AT_CROSSING = (1, 7.47, 1, 2, False, -0.0627, 0.543, -0.0085, 0.8155)
CASCADE = (1, 7.47, 2, 2, False, -7.7e-5, 0.008, 0.0085, -0.1239)


def test_events_at_one_volume_are_one_transition_compounded():
    grouped = group_paper_transitions(events(CROSSING_01, SNAP_AT_CROSSING, CASCADE))
    assert grouped["v_ml"].tolist() == [7.47]
    assert (grouped["alpha"][0], grouped["beta"][0]) == (0, 2)
    assert grouped["stable"].tolist() == [False]
    assert grouped["events"].tolist() == [3] and grouped["first"].tolist() == [0]
    # each relative change is of the state the one before left: they multiply
    for k, name in enumerate(METRICS, start=5):
        if name in COMPOUNDED:
            expected = (1 + CROSSING_01[k]) * (1 + SNAP_AT_CROSSING[k]) * (1 + CASCADE[k]) - 1
        else:  # flows of one supplied volume add
            expected = CROSSING_01[k] + SNAP_AT_CROSSING[k] + CASCADE[k]
        assert grouped[name][0] == pytest.approx(expected, rel=1e-12)
    # the pair: +81.6 % after -12.4 % is +59 %, not the +69 % of a sum
    two = group_paper_transitions(events(CASCADE, SNAP_AT_CROSSING))
    assert two["dp"][0] == pytest.approx(0.5905, abs=1e-3)


def test_a_snap_after_the_crossing_is_a_transition_of_its_own():
    """However close: 0.05 mL later the supplied volume has changed."""
    grouped = group_paper_transitions(events(CROSSING_01, SNAP_11))
    assert grouped["stable"].tolist() == [True, False]
    assert list(zip(grouped["alpha"], grouped["beta"], strict=True)) == [(0, 1), (1, 1)]
    assert grouped["events"].tolist() == [1, 1]
    just_past = (1, 7.47 + 10 * SAME_VOLUME_ML, 1, 1, False, -0.03, 0.2, 0.0, -0.4)
    assert group_paper_transitions(events(CROSSING_01, just_past))["events"].tolist() == [1, 1]
    # a wider tolerance, as an earlier counting chained events, joins them
    joined = group_paper_transitions(events(CROSSING_01, SNAP_11), same_volume_ml=1.5)
    assert joined["stable"].tolist() == [False] and joined["events"].tolist() == [2]


def test_one_volume_never_joins_across_actuators_or_directions():
    grouped = group_paper_transitions(
        events(CROSSING_01, SNAP_AT_CROSSING, CASCADE), actuator=np.array([4, 4, 5])
    )
    assert grouped["events"].tolist() == [2, 1] and grouped["actuator"].tolist() == [4, 5]
    back = (-1, 7.47, 2, 1, False, -0.06, 0.5, 0.0, 0.7)
    assert group_paper_transitions(events(CROSSING_01, back))["events"].tolist() == [1, 1]


def test_no_events_no_transitions():
    grouped = group_paper_transitions(events())
    assert all(len(grouped[name]) == 0 for name in (*EVENT_FIELDS, "first", "events"))
    assert paper_transitions([]) == []


event_rows = st.lists(
    st.tuples(
        st.sampled_from([1, -1]),
        st.sampled_from([1.0, 7.47, 7.47 + 0.5 * SAME_VOLUME_ML, 7.5, 22.6]),
        st.integers(0, 3),
        st.integers(0, 3),
        st.booleans(),
        *(st.floats(-0.9, 1.0) for _ in METRICS),
    ),
    max_size=30,
)


@settings(max_examples=200, deadline=None)
@given(event_rows, st.lists(st.integers(0, 3), min_size=30, max_size=30))
def test_grouping_keeps_the_products_and_every_event_once(rows, actuator_ids):
    columns = events(*rows)
    actuator = np.sort(np.array(actuator_ids[: len(rows)], dtype=int))
    copies = {name: values.copy() for name, values in columns.items()}
    grouped = group_paper_transitions(columns, actuator)
    for name, values in columns.items():  # pure: the input is untouched
        np.testing.assert_array_equal(values, copies[name])
    # every event in exactly one transition, in order
    assert grouped["events"].sum() == len(rows)
    assert np.all(np.diff(grouped["first"]) == grouped["events"][:-1])
    # over a path the changes are the same counted either way: the product of (1 + x)
    # over the events is that over the transitions (the sum, for the flows)
    for name in METRICS:
        if name in COMPOUNDED:
            by_event, by_transition = np.log1p(columns[name]), np.log1p(grouped[name])
        else:
            by_event, by_transition = columns[name], grouped[name]
        assert math.fsum(by_transition) == pytest.approx(math.fsum(by_event), abs=1e-9)
    for k, (start, size) in enumerate(zip(grouped["first"], grouped["events"], strict=True)):
        members = range(start, start + size)
        # a transition is made of events at one volume
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
            abs(columns["v_ml"][start] - columns["v_ml"][start - 1]) > SAME_VOLUME_ML
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


def test_a_real_pairs_crossing_and_the_snap_after_it_are_two():
    """SI-B44-T20 + SI-B44-T30: the second segment crosses its peak at 13.8 mL and the
    first snaps back over its own 0.19 mL later, at another supplied volume: a stable
    transition and an unstable one, each typed by its own states."""
    actuator = Actuator([analytical_segment(n) for n in ("SI-B44-T20", "SI-B44-T30")])
    found = transitions(quasi_static_path(actuator))
    counted = paper_transitions(found)
    assert len(counted) == len(found) and all(len(t.events) == 1 for t in counted)
    k = next(i for i, t in enumerate(found) if not t.stable)
    crossing, snap = found[k - 1], found[k]
    assert crossing.stable and 0.1 < snap.v_ml - crossing.v_ml < 0.3
    first, second = counted[k - 1], counted[k]
    assert first.stable and not second.stable
    # alpha and beta from the states on either side, read off the segments' tables
    assert first.alpha == _right_of_peak(actuator, crossing.pre.v_i_ml)
    assert first.beta == second.alpha == _right_of_peak(actuator, crossing.post.v_i_ml)
    assert second.beta == _right_of_peak(actuator, snap.post.v_i_ml)
    # the snap sends fluid from one segment to the other and releases energy, against
    # the segments' energies at its two states
    assert second.dv > 0.2
    e_pre, e_post = (actuator.energy_mj(s.v_i_ml) for s in (snap.pre, snap.post))
    assert second.dE == pytest.approx((e_post - e_pre) / e_pre, rel=1e-9) and second.dE < 0
