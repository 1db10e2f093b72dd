"""The demo protocol end to end on the simulated rig, and the file's contents against the
plant's truth: pressure within the sensor noise, volume within the pump's resolution,
length within the tracking error."""

import numpy as np
import pytest
from support.simrig import DEMO

from labrig.recording.run_reader import open_run, read_log, repetition_statuses


def test_demo_completes_with_every_repetition(demo):
    assert demo.result.status == "complete", demo.result.reason
    with open_run(demo.path) as run:
        assert repetition_statuses(run) == [("complete", "")] * 3
        assert run["entry/status"][()] == b"complete"
        assert run["entry/protocol"][()].decode() == DEMO.read_text()
        assert abs(run["entry/zero/offset_kpa"][()] - 0.8) < 0.05  # the injected offset
    assert demo.pump_is_stopped()


def test_pressure_matches_the_plant_within_sensor_noise(demo):
    plant = demo.rig.simulation.plant
    with open_run(demo.path) as run:
        for rep in (1, 2, 3):
            log = read_log(run, rep, "pressure")
            error = log.fields["value"] - plant.pressure_kpa_at(log.time_s)
            assert len(log) > 100_000  # 1 kS/s for ~2 min
            assert np.all(np.diff(log.time_s) == pytest.approx(0.001))  # no sample lost
            assert abs(np.mean(error)) < 0.03  # zeroed: only the noise's mean is left
            assert np.std(error) < 0.08  # 0.05 kPa noise + 14-bit quantisation


def test_volume_matches_the_pump_within_its_resolution(demo):
    """Every logged volume lies on the plunger's true trajectory, at its stamp: the
    driver's exchange takes no rig time on the virtual clock, so the only error is the
    pump's display resolution."""
    emulator = demo.rig.simulation.emulator
    with open_run(demo.path) as run:
        for rep in (1, 2, 3):
            log = read_log(run, rep, "pump")
            t, volume = log.time_s, log.fields["value"]
            truth = np.array([emulator.net_volume_ml(x) for x in t])
            later = np.array([emulator.net_volume_ml(x + 1.0) for x in t])
            earlier = np.array([emulator.net_volume_ml(x - 1.0) for x in t])
            standing = np.abs(later - earlier) < 1e-9
            rate_ml_s = (later - earlier) / 2.0
            # a steady motion through the whole +-1 s window
            moving = np.abs(truth - 0.5 * (later + earlier)) < 1e-9
            moving &= np.abs(rate_ml_s) > 1e-3
            assert np.all(np.abs(volume[standing] - truth[standing]) < 1e-3)
            assert moving.sum() > 500 and standing.sum() > 10
            assert np.all(np.abs(volume[moving] - truth[moving]) < 1e-3)
            assert volume.max() == pytest.approx(38.0, abs=1e-3)
            assert volume[-1] == pytest.approx(0.0, abs=1e-3)


def test_length_matches_the_plant_within_tracking_error(demo):
    plant = demo.rig.simulation.plant
    with open_run(demo.path) as run:
        for rep in (1, 2, 3):
            log = read_log(run, rep, "length")
            assert log.fields["ok"].all()
            error = log.fields["value"] - plant.length_mm_at(log.time_s)
            # frames carry their exposure time; the tracker is good to ~0.001 mm
            assert np.median(np.abs(error)) < 0.01
            assert np.max(np.abs(error)) < 0.05


def test_each_frame_is_recorded_in_the_repetition_it_was_taken_in(demo):
    """A batch of frames is recorded a camera period or two after it was taken (it is
    measured in the tracker's process meanwhile): each frame still goes to the
    repetition that was running when it was taken, and none is lost or doubled where
    one repetition ends and the next begins."""
    with open_run(demo.path) as run:
        starts = run["entry/repetitions/t_start"][:]
        times = [read_log(run, rep, "length").time_s for rep in (1, 2, 3)]
    for rep in (1, 2):
        assert times[rep - 1][-1] < starts[rep] <= times[rep][0]
        assert times[rep][0] - starts[rep] < 1 / 30
    np.testing.assert_allclose(np.diff(np.concatenate(times)), 1 / 30, atol=1e-9)
