"""Alignment, resampling and averaging against cases computed by hand."""

import numpy as np
from hypothesis import example, given, settings
from hypothesis import strategies as st

from labrig.analysis.curves import (
    DEFLATE,
    INFLATE,
    MIN_MOVE_ML,
    mean_curve,
    motion_at,
    phase_curves,
    pump_path,
    repetitions_to_average,
    resample,
    volume_at,
    volume_grid,
    with_motion_corners,
)

PUMP_T = np.array([0.0, 1.0, 2.0, 3.0, 4.0, 5.0])
PUMP_V = np.array([0.0, 1.0, 2.0, 2.0, 1.0, 0.0])  # infuse 2 mL, hold 1 s, withdraw


def test_volume_is_the_pump_log_interpolated_and_held_at_its_ends():
    t = np.array([-1.0, 0.5, 1.25, 2.5, 3.5, 6.0])
    np.testing.assert_allclose(volume_at(t, PUMP_T, PUMP_V), [0, 0.5, 1.25, 2, 1.5, 0])


def test_motion_is_the_direction_of_the_pump_interval():
    t = np.array([-0.5, 0.5, 1.999, 2.5, 3.0, 4.99, 5.0, 7.0])
    # interval [2, 3) holds; t = 3.0 starts the withdrawal; outside the log: no motion
    assert motion_at(t, PUMP_T, PUMP_V).tolist() == [0, 1, 1, 0, -1, -1, 0, 0]


def test_grid_starts_at_zero_and_stops_at_or_below_the_maximum():
    np.testing.assert_allclose(volume_grid(0.27, 0.05), [0, 0.05, 0.1, 0.15, 0.2, 0.25])
    np.testing.assert_allclose(volume_grid(0.3, 0.1), [0, 0.1, 0.2, 0.3])


def test_resample_places_bin_means_at_their_mean_volume():
    grid = np.array([0.0, 1.0, 2.0, 3.0])
    # bin 1 (0.5..1.5): samples at v 0.6, 0.8 -> mean v 0.7, mean y 10
    # bin 2 (1.5..2.5): samples at v 2.0, 2.4 -> mean v 2.2, mean y 40
    v = np.array([0.6, 0.8, 2.0, 2.4])
    y = np.array([8.0, 12.0, 30.0, 50.0])
    out = resample(v, y, grid, max_gap_ml=5.0)
    # grid 1.0 lies between (0.7, 10) and (2.2, 40): 10 + 30 * 0.3 / 1.5 = 16
    # grid 2.0 lies between them too: 10 + 30 * 1.3 / 1.5 = 36
    # grid 0 and 3 have no samples in their bins: nothing
    np.testing.assert_allclose(out, [np.nan, 16.0, 36.0, np.nan])


def test_resample_is_exact_for_a_line_up_to_the_ends():
    grid = volume_grid(2.0, 0.5)
    v = np.linspace(0.0, 2.0, 400)
    out = resample(v, 3.0 * v + 1.0, grid, max_gap_ml=1.0)
    # inside: between bin means; the ends: the line through the outermost means continued
    np.testing.assert_allclose(out, 3.0 * grid + 1.0, rtol=1e-12)


def test_resample_an_isolated_end_bin_takes_its_own_mean():
    grid = volume_grid(3.0, 1.0)
    v = np.array([0.9, 1.1, 1.2])  # all in bin 1; mean volume 1.0667, mean y 20
    out = resample(v, np.array([10.0, 20.0, 30.0]), grid, max_gap_ml=1.0)
    np.testing.assert_allclose(out, [np.nan, 20.0, np.nan, np.nan])


def test_resample_leaves_gaps_wider_than_the_limit_empty():
    grid = volume_grid(4.0, 1.0)
    v = np.array([0.0, 1.0, 4.0])
    y = np.array([0.0, 1.0, 4.0])
    # 1.0 -> 4.0 is a 3 mL gap: grid 2 and 3 stay empty although data surrounds them
    np.testing.assert_allclose(resample(v, y, grid, max_gap_ml=1.0), [0, 1, np.nan, np.nan, 4])
    np.testing.assert_allclose(resample(v, y, grid, max_gap_ml=3.0), [0, 1, 2, 3, 4])


def test_phase_curves_split_inflation_from_deflation():
    # pressure 10*v while infusing, 10*v - 5 while withdrawing (hysteresis), sampled densely
    t = np.linspace(0.0, 5.0, 5001)
    v = volume_at(t, PUMP_T, PUMP_V)
    motion = motion_at(t, PUMP_T, PUMP_V)
    p = np.where(motion < 0, 10 * v - 5, 10 * v)
    grid = volume_grid(2.0, 0.25)
    curves = phase_curves(grid, t, p, PUMP_T, PUMP_V, max_gap_ml=1.0)
    np.testing.assert_allclose(curves[INFLATE], 10 * grid, atol=1e-9)
    np.testing.assert_allclose(curves[DEFLATE], 10 * grid - 5, atol=1e-9)


def test_mean_and_sample_spread_by_hand():
    a = np.array([1.0, 2.0, np.nan, 4.0])
    b = np.array([3.0, 2.0, 5.0, 8.0])
    c = np.array([5.0, 2.0, 5.0, 6.0])
    mean = mean_curve([a, b, c])
    np.testing.assert_allclose(mean.mean, [3.0, 2.0, np.nan, 6.0])
    # sample standard deviation (n - 1): of 1, 3, 5 it is 2; of 4, 8, 6 it is 2
    np.testing.assert_allclose(mean.std, [2.0, 0.0, np.nan, 2.0])
    single = mean_curve([b])
    np.testing.assert_allclose(single.std, 0.0)


def test_the_mean_takes_the_last_completed_repetitions():
    statuses = ["complete", "complete", "faulted", "complete", "complete", "complete"]
    assert repetitions_to_average(statuses, 4) == [2, 4, 5, 6]
    assert repetitions_to_average(statuses, 10) == [1, 2, 4, 5, 6]
    assert repetitions_to_average(["aborted", "pending"], 4) == []


def _polled_motion(start_s, stop_s, rate_ml_s, period_s, phase_s, v0_ml=1.0):
    """The pump log of one motion between rests, polled every ``period_s``."""
    t = phase_s + period_s * np.arange(int((stop_s + 3.0) / period_s))
    v = v0_ml + rate_ml_s * np.clip(t - start_s, 0.0, stop_s - start_s)
    return t, v


def test_corners_put_a_start_and_stop_between_polls_back_where_they_were():
    # polls at 0.1, 0.3, 0.5, ...; the pump starts at 1.23 s and stops at 4.87 s
    t, v = _polled_motion(1.23, 4.87, 0.5, 0.2, 0.1)
    tc, vc = with_motion_corners(t, v)
    assert len(tc) == len(t) + 2
    added = sorted(set(tc) - set(t))
    np.testing.assert_allclose(added, [1.23, 4.87], atol=1e-9)
    # the interval before the start is a hold now: the specimen was at rest
    assert motion_at(np.array([1.2, 1.24]), tc, vc).tolist() == [0, 1]
    assert volume_at(np.array([1.2]), tc, vc)[0] == 1.0
    # a straight line between the straddling polls (1.1 s: 1.0 mL, 1.3 s: 1.035 mL)
    # would have put 0.0175 mL into the specimen at rest
    np.testing.assert_allclose(volume_at(np.array([1.2]), t, v), [1.0175])


def test_a_late_time_stamp_does_not_move_the_corner():
    t, v = _polled_motion(1.23, 4.87, 0.5, 0.2, 0.1)
    first_moving = np.flatnonzero(t > 1.23)[0]
    t = t.copy()
    t[first_moving] += 0.15  # this poll's stamp came 0.15 s late
    tc, _ = with_motion_corners(t, v)
    np.testing.assert_allclose(sorted(set(tc) - set(t)), [1.23, 4.87], atol=1e-9)


def test_a_withdrawal_gets_its_corners_too():
    t, v = _polled_motion(0.95, 3.05, -0.4, 0.25, 0.0, v0_ml=2.0)
    tc, vc = with_motion_corners(t, v)
    np.testing.assert_allclose(sorted(set(tc) - set(t)), [0.95, 3.05], atol=1e-9)
    assert motion_at(np.array([0.9, 1.0, 3.0, 3.1]), tc, vc).tolist() == [0, -1, -1, 0]


def test_a_motion_with_no_whole_interval_inside_is_left_as_logged():
    t = np.array([0.0, 0.2, 0.4, 0.6])
    v = np.array([0.0, 0.0, 0.05, 0.05])  # started and stopped between two polls
    tc, vc = with_motion_corners(t, v)
    np.testing.assert_array_equal(tc, t)
    np.testing.assert_array_equal(vc, v)


@settings(max_examples=60, deadline=None)
@given(
    start_s=st.floats(0.5, 2.0),
    duration_s=st.floats(1.5, 20.0),
    rate_ml_s=st.floats(0.01, 2.0) | st.floats(-2.0, -0.01),
    period_s=st.floats(0.05, 0.5),
    phase_s=st.floats(0.0, 0.05),
)
# found by a fresh-clone run: the motion ends 10 us after a poll, so the interval after
# it moves 6e-7 mL, below MIN_MOVE_ML: a hold, and the corner stays at the poll
@example(start_s=1.0, duration_s=2.00001, rate_ml_s=-0.0625, period_s=0.5, phase_s=0.0)
def test_corners_of_an_exact_log_are_exact(start_s, duration_s, rate_ml_s, period_s, phase_s):
    t, v = _polled_motion(start_s, start_s + duration_s, rate_ml_s, period_s, phase_s, 5.0)
    tc, vc = with_motion_corners(t, v)
    # the corrected log is the true volume at every time, polls or not, to the volume
    # below which an interval counts as a hold
    probe = np.linspace(t[0], t[-1], 997)
    truth = 5.0 + rate_ml_s * np.clip(probe - start_s, 0.0, duration_s)
    np.testing.assert_allclose(volume_at(probe, tc, vc), truth, rtol=0, atol=MIN_MOVE_ML)


def test_a_repetition_that_starts_mid_poll_gets_its_start_from_the_one_before():
    # the runner entered repetition 2 between its last poll at rest (t = 9.9, 0 mL, in
    # repetition 1's log) and the first poll of the motion (t = 10.1): the pump started
    # at 10.03 s at 0.5 mL/s
    t, v = _polled_motion(10.03, 14.0, 0.5, 0.2, 10.1 - 0.2 * 50, v0_ml=0.0)
    t, v = t[t > 10.0], v[t > 10.0]  # what repetition 2's log holds
    alone_t, alone_v = pump_path(t, v)
    assert alone_t[0] == t[0] and alone_v[0] > 0  # no reading at rest: no start
    path_t, path_v = pump_path(t, v, before=(9.9, 0.0))
    np.testing.assert_allclose(sorted(set(path_t) - set(t) - {9.9}), [10.03, 14.0], atol=1e-9)
    np.testing.assert_allclose(volume_at(np.array([10.0, 10.5]), path_t, path_v), [0.0, 0.235])
    # a reading from before that is not older than the log is ignored
    same_t, _ = pump_path(t, v, before=(t[0], 0.0))
    assert same_t[0] == t[0]
