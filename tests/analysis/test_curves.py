"""Alignment, resampling and averaging against cases computed by hand."""

import numpy as np

from labrig.analysis.curves import (
    DEFLATE,
    INFLATE,
    mean_curve,
    motion_at,
    phase_curves,
    repetitions_to_average,
    resample,
    volume_at,
    volume_grid,
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
