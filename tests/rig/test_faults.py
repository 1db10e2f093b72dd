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
from simrig import run_sim, short_protocol, when_volume_exceeds

from labrig.storage import open_run, read_log, repetition_statuses

SPEED = None  # governed: as fast as the host keeps every sample, so load cannot thin frames
# The overpressure tests time the stop: the host's latency (a thread waiting for the
# GIL, a busy CI machine) counts times the clock's speed in rig time, so they run at a
# fixed, slower speed: a 20 ms hiccup is 0.2 s of rig time at 10x, 1 s at 50x.
STOP_TIMING_SPEED = 10.0


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


def inject_after(volume_ml, action):
    def inject(rig):
        if when_volume_exceeds(rig, volume_ml):
            action(rig)

    return inject


def test_serial_disconnect_faults_the_run(tmp_path):
    outcome = run_sim(
        tmp_path,
        short_protocol(),
        inject=inject_after(5.0, lambda rig: rig.simulation.emulator.disconnect()),
        speed=SPEED,
    )
    assert outcome.result.status == "faulted"
    assert outcome.result.reason.startswith("pump:")
    assert_kept_data_up_to_the_fault(outcome)
    with open_run(outcome.path) as run:
        assert repetition_statuses(run)[0][0] == "faulted"
        assert repetition_statuses(run)[1] == ("pending", "")


def test_stall_stops_the_pump_and_faults_the_run(tmp_path):
    outcome = run_sim(
        tmp_path,
        short_protocol(),
        inject=inject_after(5.0, lambda rig: rig.simulation.emulator.stall()),
        speed=SPEED,
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
        speed=SPEED,
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
        speed=SPEED,
    )
    assert outcome.result.status == "faulted"
    assert "markers lost" in outcome.result.reason
    assert outcome.pump_is_stopped()
    with open_run(outcome.path) as run:
        length = read_log(run, 1, "length")
    ok = length.fields["ok"]
    assert ok[0] and not ok[-1]
    assert np.all(np.isnan(length.fields["value"][~ok]))  # NaN, never a wrong number
    lost_s = length.time_s[-1] - length.time_s[np.flatnonzero(ok)[-1] + 1]
    assert 10.0 <= lost_s < 12.0  # tripped at the first frame 10 s after the loss


def test_overpressure_aborts_before_the_limit_is_passed_by_much(tmp_path):
    outcome = run_sim(tmp_path, short_protocol(max_pressure_kpa=30), speed=STOP_TIMING_SPEED)
    assert outcome.result.status == "aborted"
    assert "above the limit 30 kPa" in outcome.result.reason
    assert outcome.pump_is_stopped()
    _, pressure = recorded_until_s(outcome.path)
    assert 30.0 < pressure.max() < 33.0  # the stop comes within one loop period


def test_ctrl_c_stops_safely(tmp_path):
    def interrupt(rig):
        if when_volume_exceeds(rig, 5.0):
            os.kill(os.getpid(), signal.SIGINT)

    outcome = run_sim(tmp_path, short_protocol(), inject=interrupt, speed=SPEED)
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

        outcome = run_sim(tmp_path, short_protocol(), inject=interrupt_twice, speed=SPEED)
    finally:
        signal.signal(signal.SIGINT, previous)
    assert outcome.result.status == "aborted"
    assert "operator" in outcome.result.reason
    assert outcome.pump_is_stopped()
    with open_run(outcome.path) as run:
        assert run["entry/status"][()] == b"aborted"


def test_interlock_trips_while_the_main_loop_is_blocked(tmp_path):
    """A main thread stuck for a long time cannot delay the pressure stop: the
    interlocks run in the acquisition threads."""
    import labrig.runner as runner_module

    original = runner_module.Runner._report_progress
    blocked = threading.Event()

    def stuck(self):
        if not blocked.is_set():
            blocked.set()
            time.sleep(3.0)  # 30 s of rig time at 10x: long past the limit
        original(self)

    runner_module.Runner._report_progress = stuck
    try:
        outcome = run_sim(tmp_path, short_protocol(max_pressure_kpa=30), speed=STOP_TIMING_SPEED)
    finally:
        runner_module.Runner._report_progress = original
    assert blocked.is_set()
    assert outcome.result.status == "aborted"
    _, pressure = recorded_until_s(outcome.path)
    assert pressure.max() < 33.0


def test_sigkill_leaves_a_readable_file_with_the_data(tmp_path):
    protocol = tmp_path / "p.yaml"
    protocol.write_text(short_protocol())
    out = tmp_path / "killed.h5"
    process = subprocess.Popen(
        [
            sys.executable,
            "-m",
            "labrig",
            "run",
            str(protocol),
            "--sim",
            "--out",
            str(out),
            "--speed",
            "10",
        ],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
    )
    deadline = time.monotonic() + 60
    while not out.exists() and time.monotonic() < deadline:
        assert process.poll() is None, process.stderr.read().decode()
        time.sleep(0.1)
    time.sleep(4.0)
    killed_at = time.monotonic()
    os.kill(process.pid, signal.SIGKILL)
    process.wait()
    assert out.exists()
    with pytest.raises(OSError):
        h5py.File(out, "r")  # the killed writer's flag is set
    with open_run(out) as run:
        pressure = read_log(run, 1, "pressure")
        assert run["entry/status"][()] == b"running"
    # 4 s of host time at 10x is 40 s of rig time; at most 1 s of host time is lost
    span_s = pressure.time_s[-1] - pressure.time_s[0]
    assert span_s > (4.0 - 1.0 - (time.monotonic() - killed_at)) * 10.0 - 10.0
    assert len(pressure) > 10_000
