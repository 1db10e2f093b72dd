"""Faults injected mid-run on the simulated rig: each stops the pump (where it can still
be reached), marks the run with the reason, and keeps every sample recorded before."""

import os
import signal
import subprocess
import sys
import threading
import time

import h5py
import numpy as np
import pytest
from support.simrig import run_sim, short_protocol, when_volume_exceeds

from labrig.errors import InputError
from labrig.recording.run_reader import open_run, read_log, repetition_statuses
from labrig.run.runner import Timing

PRESSURE_PERIOD_S = Timing.pressure_period_s  # the runner reads the DAQ this often
CAMERA_PERIOD_S = Timing.camera_period_s  # and records the camera's frames this often


def recorded_until_s(path, log="pressure"):
    with open_run(path) as run:
        series = read_log(run, 1, log)
        return series.time_s, series.fields["value"]


def assert_kept_data_up_to_the_fault(outcome, fault_volume_ml=5.0):
    t, _ = recorded_until_s(outcome.path)
    _, volume = recorded_until_s(outcome.path, "pump")
    assert len(t) > 1000 and np.all(np.diff(t) > 0)
    # samples from just before the fault are there (the pump is polled every 0.2 s)
    assert volume.max() >= fault_volume_ml - 1.0
    with open_run(outcome.path) as run:
        assert run["entry/status"][()].decode() == outcome.result.status


def pump_stopped_at(outcome, t_s):
    """The first of the times ``t_s`` from which the emulated plunger stood still."""
    emulator = outcome.rig.simulation.emulator
    volume = np.array([emulator.net_volume_ml(x) for x in t_s])
    moving = np.flatnonzero(np.abs(volume - volume[-1]) > 1e-9)
    return t_s[moving[-1] + 1]


def inject_after(volume_ml, action):
    def inject(rig):
        if when_volume_exceeds(rig, volume_ml):
            action(rig)

    return inject


def test_serial_disconnect_faults_the_run(tmp_path):
    """A pulled cable that never comes back: the stop cannot be sent, and the run says
    so first (the pump keeps running its last command)."""
    outcome = run_sim(
        tmp_path,
        short_protocol(),
        inject=inject_after(5.0, lambda rig: rig.simulation.emulator.disconnect()),
    )
    assert outcome.result.status == "faulted"
    assert not outcome.result.stop_confirmed
    assert outcome.result.reason.startswith("PUMP STOP NOT CONFIRMED: press Stop on the pump")
    assert "; pump: lost the serial port" in outcome.result.reason
    assert_kept_data_up_to_the_fault(outcome)
    with open_run(outcome.path) as run:
        assert repetition_statuses(run)[0][0] == "faulted"
        assert repetition_statuses(run)[1] == ("pending", "")


def test_stall_stops_the_pump_and_faults_the_run(tmp_path):
    outcome = run_sim(
        tmp_path,
        short_protocol(),
        inject=inject_after(5.0, lambda rig: rig.simulation.emulator.stall()),
    )
    assert outcome.result.status == "faulted"
    assert "stalled" in outcome.result.reason
    assert outcome.pump_is_stopped()
    assert_kept_data_up_to_the_fault(outcome)


def test_daq_timeout_stops_the_pump(tmp_path):
    outcome = run_sim(
        tmp_path,
        short_protocol(),
        inject=inject_after(5.0, lambda rig: rig.simulation.daq_tasks[-1].inject_read_timeout()),
    )
    assert outcome.result.status == "faulted"
    assert outcome.result.reason.startswith("pressure:")
    assert outcome.pump_is_stopped()
    assert_kept_data_up_to_the_fault(outcome)


def test_lost_markers_fault_the_run_after_the_allowed_gap(tmp_path):
    outcome = run_sim(
        tmp_path,
        short_protocol(),
        inject=inject_after(5.0, lambda rig: rig.simulation.camera.hide_marker(0)),
    )
    assert outcome.result.status == "faulted"
    assert "markers lost" in outcome.result.reason
    assert outcome.pump_is_stopped()
    with open_run(outcome.path) as run:
        length = read_log(run, 1, "length")
    ok = length.fields["ok"]
    assert ok[0] and not ok[-1]
    assert np.all(np.isnan(length.fields["value"][~ok]))  # NaN, never a wrong number
    first_lost = np.flatnonzero(ok)[-1] + 1
    # tripped at the frame exactly 10 s after the first frame without markers (2 fps):
    # every frame up to it is recorded, and so are the frames taken until the trip
    trip = first_lost + 20  # 10 s at 2 fps
    assert len(length) > trip
    assert length.time_s[trip] - length.time_s[first_lost] == pytest.approx(10.0, abs=1e-9)
    assert outcome.result.reason.startswith("camera: markers lost for 10.0 s")
    assert np.all(np.diff(length.time_s) == pytest.approx(0.5))  # no frame missing
    # a batch of frames is measured in the tracker's process while the next one is
    # taken: the trip frame's batch is judged one camera period after its last frame
    batch_frames = round(CAMERA_PERIOD_S * 2)
    assert len(length) - (trip + 1) < 2 * batch_frames
    t_pump, _ = recorded_until_s(outcome.path, "pump")
    # the pump stopped within two camera periods of the trip frame
    trip_s = length.time_s[trip]
    assert trip_s < pump_stopped_at(outcome, t_pump) <= trip_s + 2 * CAMERA_PERIOD_S + 0.2


def test_overpressure_trips_at_the_first_sample_above_the_limit(tmp_path):
    outcome = run_sim(tmp_path, short_protocol(max_pressure_kpa=30))
    assert outcome.result.status == "aborted"
    t, pressure = recorded_until_s(outcome.path)
    first = int(np.flatnonzero(pressure > 30.0)[0])
    assert outcome.result.reason == (
        f"pressure {pressure[first]:.1f} kPa above the limit 30 kPa at t = {t[first]:.2f} s"
    )
    assert outcome.pump_is_stopped()
    # the pump stopped at the read of the block holding that sample
    assert t[first] < pump_stopped_at(outcome, t) <= t[first] + PRESSURE_PERIOD_S
    assert np.all(np.diff(t) == pytest.approx(0.001))  # and no sample is missing


def test_ctrl_c_stops_safely(tmp_path):
    def interrupt(rig):
        if when_volume_exceeds(rig, 5.0):
            os.kill(os.getpid(), signal.SIGINT)

    outcome = run_sim(tmp_path, short_protocol(), inject=interrupt)
    assert outcome.result.status == "aborted"
    assert outcome.result.reason == "stopped by the operator (Ctrl-C)"
    assert outcome.pump_is_stopped()
    assert_kept_data_up_to_the_fault(outcome)


def test_second_ctrl_c_stops_now(tmp_path):
    # a Ctrl-C arriving after the run restored the handler must not end pytest
    previous = signal.signal(signal.SIGINT, lambda *args: None)
    try:

        def interrupt_twice(rig):
            if when_volume_exceeds(rig, 5.0):
                os.kill(os.getpid(), signal.SIGINT)
                time.sleep(0.005)
                os.kill(os.getpid(), signal.SIGINT)

        outcome = run_sim(tmp_path, short_protocol(), inject=interrupt_twice)
    finally:
        signal.signal(signal.SIGINT, previous)
    assert outcome.result.status == "aborted"
    assert "operator" in outcome.result.reason
    assert outcome.pump_is_stopped()
    with open_run(outcome.path) as run:
        assert run["entry/status"][()] == b"aborted"


def test_interlock_trips_while_the_main_loop_is_away(tmp_path):
    """A main thread away for a long rig time cannot delay the pressure stop: the
    interlocks run in the acquisition threads. (A main thread blocked outside the
    clock holds virtual time still, so on the simulated rig only rig time can pass.)"""
    import labrig.run.runner as runner_module

    original = runner_module.Runner._report_progress
    away = threading.Event()

    def stuck(self):
        if not away.is_set():
            away.set()
            self.clock.sleep(60.0)  # long past the limit
        original(self)

    runner_module.Runner._report_progress = stuck
    try:
        outcome = run_sim(tmp_path, short_protocol(max_pressure_kpa=30))
    finally:
        runner_module.Runner._report_progress = original
    assert away.is_set()
    assert outcome.result.status == "aborted"
    t, pressure = recorded_until_s(outcome.path)
    first = int(np.flatnonzero(pressure > 30.0)[0])
    assert t[first] < pump_stopped_at(outcome, t) <= t[first] + PRESSURE_PERIOD_S


def flushed_pressure_samples(path) -> int:
    """Pressure samples of repetition 1 a reader sees in a run file being written."""
    try:
        with open_run(path) as run:
            return len(read_log(run, 1, "pressure"))
    except (OSError, KeyError, InputError):
        return 0  # not created yet, or caught between the layout and the first flush


def _stat(pid):
    """(state, parent pid) of a process, from /proc; None once it is gone."""
    try:
        with open(f"/proc/{pid}/stat") as f:
            fields = f.read().rsplit(")", 1)[1].split()
    except OSError:
        return None
    return fields[0], int(fields[1])


def children_of(pid):
    return [int(p) for p in os.listdir("/proc") if p.isdigit() and (_stat(p) or ("", 0))[1] == pid]


def is_running(pid):
    stat = _stat(pid)
    return stat is not None and stat[0] not in ("Z", "X")


def test_sigkill_leaves_a_readable_file_with_the_data(tmp_path):
    protocol = tmp_path / "p.yaml"
    protocol.write_text(short_protocol())
    out = tmp_path / "killed.h5"
    command = ["run", str(protocol), "--sim", "--out", str(out), "--speed", "10"]
    process = subprocess.Popen(
        [sys.executable, "-m", "labrig", *command],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
    )
    # kill it mid-run, once the file shows 20 s of pressure (whatever the host's speed)
    deadline = time.monotonic() + 120
    while flushed_pressure_samples(out) < 20_000 and time.monotonic() < deadline:
        assert process.poll() is None, process.stderr.read().decode()
        time.sleep(0.1)
    seen = flushed_pressure_samples(out)
    helpers = children_of(process.pid)
    os.kill(process.pid, signal.SIGKILL)
    process.wait()
    # the run's helper processes (the marker tracker's) see their pipe close and end
    assert helpers, "the run had no helper process to check"
    deadline = time.monotonic() + 30
    while any(is_running(pid) for pid in helpers) and time.monotonic() < deadline:
        time.sleep(0.1)
    assert not any(is_running(pid) for pid in helpers)
    with pytest.raises(OSError):
        h5py.File(out, "r")  # the killed writer's flag is set
    with open_run(out) as run:
        pressure = read_log(run, 1, "pressure")
        assert run["entry/status"][()] == b"running"
    # everything a reader saw before the kill is still there, without a gap
    assert len(pressure) >= seen >= 20_000
    assert np.all(np.diff(pressure.time_s) == pytest.approx(0.001))
