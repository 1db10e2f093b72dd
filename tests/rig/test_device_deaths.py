"""Devices that die the ways they die at the bench, on the simulated rig: each stops the
pump within a second of rig time, ends the run faulted with a reason that says what
died, and keeps every sample and frame taken before."""

import re

import numpy as np
import pytest
from nidaqmx.error_codes import DAQmxErrors
from nidaqmx.errors import DaqError
from support.simrig import run_sim, short_protocol, when_volume_exceeds

from labrig.config.rig_file import PressureConfig, PumpConfig, RigConfig, SimConfig
from labrig.recording.run_reader import open_run, read_log

FAULT_ML = 5.0


def supply_measured(seed=0) -> RigConfig:
    return RigConfig(
        pump=PumpConfig(port="emulator"),
        pressure=PressureConfig(supply_channel="Dev1/ai1"),
        sim=SimConfig(seed=seed),
    )


def strike_at(volume_ml, action, seen):
    """At the rig time the specimen holds ``volume_ml``: note the time, then act."""

    def inject(rig):
        if when_volume_exceeds(rig, volume_ml):
            seen.append(rig.clock.now())
            action(rig)

    return inject


def plunger_stopped_after_s(outcome, fault_s) -> float:
    """Rig seconds from the fault to the plunger's last movement (emulated firmware)."""
    emulator = outcome.rig.simulation.emulator
    grid = np.arange(fault_s, outcome.end_s + 30.0, 0.01)
    volume = np.array([emulator.net_volume_ml(t) for t in grid])
    moving = np.flatnonzero(np.abs(volume - volume[-1]) > 1e-9)
    return 0.0 if len(moving) == 0 else grid[moving[-1] + 1] - fault_s


def assert_samples_kept_up_to(outcome, fault_s):
    with open_run(outcome.path) as run:
        assert run["entry/status"][()].decode() == outcome.result.status
        t = read_log(run, 1, "pressure").time_s
    before = t[t < fault_s]
    np.testing.assert_allclose(np.diff(before), 0.001, rtol=1e-6)  # none missing
    assert before[-1] >= fault_s - 0.0015


def run_with_daq_failure(tmp_path, failure, config=None):
    seen = []
    outcome = run_sim(
        tmp_path,
        short_protocol(),
        config=config,
        inject=strike_at(FAULT_ML, lambda rig: rig.simulation.daq_tasks[-1].fail(failure), seen),
    )
    return outcome, seen[0]


@pytest.mark.parametrize(
    ("failure", "config", "reason"),
    [
        ("vout-cut", None, "outside the sensor's range"),
        ("supply-cut", None, "outside the sensor's range"),  # assumed supply: -4.4 kPa
        ("supply-cut", supply_measured(), "not a number"),  # measured supply: 0/0
    ],
    ids=["vout-wire", "supply-wire", "supply-wire-measured-nan"],
)
def test_a_dead_sensor_stops_the_pump(tmp_path, failure, config, reason):
    """A cut wire reads -4.4 kPa or NaN, never high: a pressure ceiling alone would let
    the pump go on to the step's target."""
    outcome, fault_s = run_with_daq_failure(tmp_path, failure, config)
    assert outcome.result.status == "faulted"
    assert reason in outcome.result.reason
    assert plunger_stopped_after_s(outcome, fault_s) <= 1.0
    assert_samples_kept_up_to(outcome, fault_s)


@pytest.mark.parametrize(
    ("failure", "reason"),
    [("frozen", "pressure reading frozen"), ("vout-floating", "pressure sensor wire open")],
)
def test_a_sensor_dead_in_range_stops_the_pump_from_its_own_signal(tmp_path, failure, reason):
    """A frozen reading stops dithering; a cut output wire reads above the sensor's band
    (the pull-up). Neither needs the specimen's model: the pump stops within a second."""
    seen = []
    outcome = run_sim(
        tmp_path,
        short_protocol(),
        inject=strike_at(0.5, lambda rig: rig.simulation.daq_tasks[-1].fail(failure), seen),
    )
    assert outcome.result.status == "faulted"
    assert outcome.result.reason.startswith(reason)
    assert plunger_stopped_after_s(outcome, seen[0]) <= 1.0
    assert_samples_kept_up_to(outcome, seen[0])


def test_a_wire_cut_before_the_run_is_refused_at_the_zeroing(tmp_path):
    """Cut before the run: with the pull-up the zero reads above the band and names the
    wire; on a rig without it the open input's 27 kPa is no zero either."""
    for pull_up_kohm, reason in ((4.7, "its output wire is open"), (None, "about 27 kPa")):
        config = RigConfig(
            pump=PumpConfig(port="emulator"),
            pressure=PressureConfig(pull_up_kohm=pull_up_kohm),
            sim=SimConfig(),
        )
        outcome = run_sim(
            tmp_path,
            short_protocol(),
            config=config,
            inject=lambda rig: _cut_before_zeroing(rig),
            name=f"cut-{pull_up_kohm}.h5",
        )
        assert outcome.result.status == "faulted", outcome.result.reason
        assert reason in outcome.result.reason
        assert outcome.rig.simulation.emulator.net_volume_ml(outcome.end_s) == 0.0


def _cut_before_zeroing(rig):
    rig.clock.wait_for(lambda: rig.simulation.daq_tasks, timeout_s=60.0)
    rig.simulation.daq_tasks[-1].fail("vout-floating", at_s=0.0)


def test_a_stalled_daq_stops_the_pump_after_half_a_second_without_samples(tmp_path):
    """The watch looks when the newest sample's allowance runs out, not at its next
    tick: the silence is found at 0.50 s."""
    outcome, fault_s = run_with_daq_failure(tmp_path, "stall")
    assert outcome.result.status == "faulted"
    assert re.match(r"pressure: no sample for 0\.50 s", outcome.result.reason)
    assert 0.5 <= plunger_stopped_after_s(outcome, fault_s) <= 0.7
    assert_samples_kept_up_to(outcome, fault_s)


def test_an_unplugged_daq_faults_the_run_and_the_file_is_finalised(tmp_path):
    """Every call after the unplug fails, stop and close too: the run still ends with
    its file finalised, the samples in the host buffer recorded."""
    outcome, fault_s = run_with_daq_failure(tmp_path, "vanish")
    assert outcome.result.status == "faulted"
    assert "-201003" in outcome.result.reason and "cannot be reached" in outcome.result.reason
    assert plunger_stopped_after_s(outcome, fault_s) <= 1.0
    assert_samples_kept_up_to(outcome, fault_s)


def test_a_daq_whose_close_raises_still_leaves_a_finalised_file(tmp_path):
    """DAQmx raising from task.close() (the device gone) at the end of a run that went
    well: the file is still finalised, complete, with every sample."""

    def break_close(rig):
        rig.clock.wait_for(lambda: len(rig.simulation.daq_tasks) >= 2, timeout_s=60.0)
        task = rig.simulation.daq_tasks[-1]  # the acquisition's, after the zeroing's

        def close():
            raise DaqError("Device cannot be accessed.", DAQmxErrors.DEV_CANNOT_BE_ACCESSED.value)

        task.close = close

    outcome = run_sim(tmp_path, short_protocol(), inject=break_close)
    assert outcome.result.status == "complete", outcome.result.reason
    with open_run(outcome.path) as run:
        assert run["entry/status"][()] == b"complete"
        t = read_log(run, 2, "pressure").time_s
    assert len(t) > 1000 and np.allclose(np.diff(t), 0.001)


def test_no_pressure_sample_no_pump_start(tmp_path):
    """A DAQ that delivers nothing from the start: the pump never moves (an empty block
    is not a reading, so the first infuse never gets its pressure sample)."""

    def stall_acquisition(rig):
        rig.clock.wait_for(lambda: len(rig.simulation.daq_tasks) >= 2, timeout_s=60.0)
        rig.simulation.daq_tasks[-1].fail("stall", at_s=0.0)

    outcome = run_sim(tmp_path, short_protocol(), inject=stall_acquisition)
    assert outcome.result.status == "faulted"
    assert "no pressure" in outcome.result.reason or "no sample" in outcome.result.reason
    assert outcome.rig.simulation.emulator.net_volume_ml(outcome.end_s + 30.0) == 0.0


def test_a_silent_pump_is_stopped_at_once_in_rig_time(tmp_path):
    """The pump's reply line dies mid-reply: the exchange times out (host time, while
    rig time stands still) and the stop, written first, stops the plunger."""
    seen = []
    config = RigConfig(pump=PumpConfig(port="emulator"), sim=SimConfig(reply_timeout_s=1.0))
    outcome = run_sim(
        tmp_path,
        short_protocol(),
        config=config,
        inject=strike_at(FAULT_ML, lambda rig: rig.simulation.emulator.go_silent(), seen),
    )
    assert outcome.result.status == "faulted"
    assert "no complete reply from the pump" in outcome.result.reason
    assert plunger_stopped_after_s(outcome, seen[0]) <= 0.3
    assert_samples_kept_up_to(outcome, seen[0])


@pytest.mark.parametrize("death", ["unplugged", "frames-stop", "clock-jump"])
def test_the_frames_before_a_camera_fault_are_kept(tmp_path, death):
    """The batch still being tracked when the camera died is recorded (the last 1-2 s of
    frames, easily lost on the way out); the pump stops within a second."""
    seen = []
    act = {
        "unplugged": lambda rig: rig.simulation.camera.release(),
        "frames-stop": lambda rig: rig.simulation.camera.stop_frames(),
        "clock-jump": lambda rig: rig.simulation.camera.jump_clock(5.0),
    }[death]
    outcome = run_sim(
        tmp_path, short_protocol(camera_fps=10), inject=strike_at(FAULT_ML, act, seen)
    )
    fault_s = seen[0]
    with open_run(outcome.path) as run:
        frames = read_log(run, 1, "length").time_s
    np.testing.assert_allclose(np.diff(frames), 0.1, rtol=1e-6)  # no frame missing
    # every frame exposed before the fault (10 fps), the last batch tracked included
    assert frames[-1] >= fault_s - 0.1 - 1e-6
    assert outcome.result.status == "faulted"
    assert outcome.result.reason.startswith("camera:")
    assert plunger_stopped_after_s(outcome, fault_s) <= 1.0
