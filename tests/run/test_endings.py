"""Every way a run ends stops the pump and says so: Ctrl-C in every clock mode (paced,
holding, at a technician's prompt), an exchange cut short by the operator's stop, a
stop the pump never confirms, a pump that re-enumerates, a slow disk, a camera slow to
start. All on the simulated rig's virtual clock; host timeouts are deadlock guards."""

import os
import signal
import subprocess
import sys
import textwrap
import threading

import numpy as np
import pytest
from support.liverun import poll_until
from support.simrig import run_sim, when_volume_exceeds

from labrig.config.rig_file import PumpConfig, RigConfig, SimConfig, sim_rig_config
from labrig.errors import InputError
from labrig.recording.run_reader import open_run, read_log
from labrig.run.acquisition import Timing
from labrig.run.pump_stop import PUMP_STOP_NOT_CONFIRMED
from labrig.run.technician import ConsoleTechnician

PROTOCOL = textwrap.dedent(
    """\
    name: ending test
    specimen: {{segments: [SI-B46-T20, SI-B46-T22], fittings_length_mm: 10}}
    rig: sim
    limits: {{max_pressure_kpa: {max_kpa}, max_volume_ml: 40}}
    acquisition: {{pressure_rate_hz: 1000, camera_fps: {fps}}}
    steps:
      - zero_pressure: {{duration_s: 0.5}}
    {steps}"""
)


def protocol(steps: str, max_kpa=95, fps=0) -> str:
    return PROTOCOL.format(max_kpa=max_kpa, fps=fps, steps=textwrap.indent(steps, "  "))


INFUSE = "- infuse: {rate_ml_min: 60, volume_ml: 10}\n"
HOLD = "- infuse: {rate_ml_min: 60, volume_ml: 2}\n- hold: {seconds: 600}\n"
# a simulated pump whose silence costs 1 s of host time, not the default 10 s
QUICK_TIMEOUT = RigConfig(pump=PumpConfig(port="emulator"), sim=SimConfig(reply_timeout_s=1.0))


def plunger_still_after(outcome, t_s) -> bool:
    emulator = outcome.rig.simulation.emulator
    return emulator.net_volume_ml(t_s) == emulator.net_volume_ml(outcome.end_s + 60.0)


def ctrl_c(rig):
    """Ctrl-C, then hold rig time still (a host wait in a participant of the clock)
    until the stop it sends has reached the pump: the stop lands at the Ctrl-C's rig
    instant on any host, paced or not."""
    received = rig.simulation.emulator.received
    stops = sum(line == "stop" for line in list(received))
    os.kill(os.getpid(), signal.SIGINT)
    for _ in range(60_000):  # a 60 s deadlock guard
        if sum(line == "stop" for line in list(received)) > stops:
            return
        threading.Event().wait(0.001)


def test_ctrl_c_while_paced_stops_the_pump(tmp_path):
    """At --speed 5 the main thread waits inside the clock's hand-over almost all the
    time; Ctrl-C must still stop the run at once, not when the step ends."""

    def interrupt(rig):
        if when_volume_exceeds(rig, 2.0):
            ctrl_c(rig)

    outcome = run_sim(
        tmp_path, protocol(INFUSE), inject=interrupt, config=sim_rig_config(speed=5.0)
    )
    assert (outcome.result.status, outcome.result.reason) == (
        "aborted",
        "stopped by the operator (Ctrl-C)",
    )
    emulator = outcome.rig.simulation.emulator
    # stopped within one pump poll (0.2 s: 0.2 mL) of 2 mL, not at the step's 10 mL
    assert 2.0 < emulator.net_volume_ml(outcome.end_s + 60.0) < 2.3
    assert plunger_still_after(outcome, outcome.end_s)


@pytest.mark.parametrize("speed", [None, 2.0])
def test_ctrl_c_while_holding_ends_the_hold(tmp_path, speed):
    """A 10-minute hold, paced or not, ends at the Ctrl-C."""

    def interrupt(rig):
        rig.clock.sleep(3.0)  # in the hold
        ctrl_c(rig)

    outcome = run_sim(tmp_path, protocol(HOLD), inject=interrupt, config=sim_rig_config(speed))
    assert outcome.result.reason == "stopped by the operator (Ctrl-C)"
    assert outcome.end_s < 10.0  # rig seconds: the hold did not run its 600 s


def test_ctrl_c_at_a_prompt_withdraws_it(tmp_path):
    """A technician's prompt open when a trip comes gives way, and the screen says
    why instead of asking for Enter."""
    asked, released, shown = threading.Event(), threading.Event(), []

    def ask(question):
        asked.set()
        released.wait(60.0)  # nobody at the keyboard (a deadlock guard, not a timing)

    def arm(rig):
        rig.technician = ConsoleTechnician(rig.clock, ask=ask, show=shown.append)

    def interrupt(rig):
        rig.clock.wait_for(asked.is_set, 3600.0)
        ctrl_c(rig)

    steps = "- infuse: {rate_ml_min: 60, volume_ml: 2}\n- prompt: {message: close the valve}\n"
    try:
        outcome = run_sim(tmp_path, protocol(steps), inject=interrupt, prepare=arm)
        still_asking = not released.is_set()
    finally:
        released.set()
    assert still_asking  # the run ended while the question was open
    assert outcome.result.reason == "stopped by the operator (Ctrl-C)"
    assert shown == [
        "\n>>> The run stopped (stopped by the operator (Ctrl-C)): do not press Enter, "
        "the prompt is withdrawn."
    ]


def test_ctrl_c_during_a_slow_run_command_stays_the_reason(tmp_path):
    """The pump answers 'irun' slowly (normal: > 0.5 s); the operator's Ctrl-C comes
    meanwhile. Its stop cuts the exchange short, and the Ctrl-C is the recorded reason."""

    def interrupt(rig):
        emulator = rig.simulation.emulator
        emulator.slow_replies(0.8, commands=("irun",))
        # a host thread: the main thread holds rig time still while it waits for irun
        threading.Thread(target=kill_at_irun, args=(emulator,), daemon=True).start()

    def kill_at_irun(emulator):
        for _ in range(6000):  # 60 s deadlock guard
            if "irun" in emulator.received:
                os.kill(os.getpid(), signal.SIGINT)
                return
            threading.Event().wait(0.01)

    outcome = run_sim(tmp_path, protocol(INFUSE), inject=interrupt, config=QUICK_TIMEOUT)
    assert (outcome.result.status, outcome.result.reason) == (
        "aborted",
        "stopped by the operator (Ctrl-C)",
    )
    assert plunger_still_after(outcome, outcome.end_s)


def test_an_unconfirmed_stop_faults_the_run_and_says_so(tmp_path):
    """The pump's reply line dies as the pressure ceiling trips: the stop acts but is
    never confirmed. The run is faulted, and both the result and the file lead with
    the warning."""

    def die_at_the_stop(rig):
        rig.simulation.emulator.go_silent_at_stop()

    outcome = run_sim(
        tmp_path, protocol(INFUSE, max_kpa=20), inject=die_at_the_stop, config=QUICK_TIMEOUT
    )
    result = outcome.result
    assert result.status == "faulted"
    assert not result.stop_confirmed
    assert result.reason.startswith(PUMP_STOP_NOT_CONFIRMED + " (")
    assert "pressure" in result.reason and "above the limit 20 kPa" in result.reason
    with open_run(outcome.path) as run:
        assert run["entry/status"][()] == b"faulted"
        assert run["entry/reason"][()].decode().startswith(PUMP_STOP_NOT_CONFIRMED)
        assert run["entry/pump_stop_confirmed"][()] == np.False_


def test_a_confirmed_stop_is_no_warning(tmp_path):
    outcome = run_sim(tmp_path, protocol(INFUSE, max_kpa=20))
    assert outcome.result.status == "aborted"
    assert outcome.result.stop_confirmed
    assert PUMP_STOP_NOT_CONFIRMED not in outcome.result.reason
    with open_run(outcome.path) as run:
        assert run["entry/pump_stop_confirmed"][()] == np.True_


def test_a_pump_that_re_enumerates_is_found_again_and_stopped(tmp_path):
    """The pump drops off USB mid-infusion and comes back 0.5 s later as another pty
    under the same by-id link: the driver closes the dead port, opens the link again
    and stops the pump there."""
    ports = []

    def replug(rig):
        emulator = rig.simulation.emulator
        if when_volume_exceeds(rig, 3.0):
            ports.append(emulator.tty_path)
            emulator.re_enumerate(0.5)

    outcome = run_sim(tmp_path, protocol(INFUSE), inject=replug)
    emulator = outcome.rig.simulation.emulator
    assert outcome.result.status == "faulted"
    # the recorded reason is true at the run's end: the pump was reached and stopped
    reason = outcome.result.reason
    assert reason.startswith("pump: lost the serial port ")
    assert reason.endswith("); the pump was found again and stopped")
    assert "may still be running" not in reason
    assert outcome.result.stop_confirmed
    with open_run(outcome.path) as run:
        assert run["entry/reason"][()].decode() == reason
    assert emulator.tty_path not in (None, ports[0])  # came back as another pty
    assert emulator.net_volume_ml(outcome.end_s + 60.0) < 9.0  # stopped short of 10 mL
    assert plunger_still_after(outcome, outcome.end_s)


def slow_disk(rig):
    """Every write to the run file takes 0.5 s of rig time."""
    rig.simulation.disk.write_s = 0.5
    return rig.simulation.disk.write


def test_a_slow_disk_does_not_delay_the_pressure_stop(tmp_path):
    """Every write to the run file takes 0.5 s of rig time (a USB stick, a network
    share): the ceiling still trips at the read of the block holding the first sample
    above it, and every sample is in the file."""
    outcome = run_sim(tmp_path, protocol(INFUSE, max_kpa=20), tap=slow_disk)
    assert outcome.result.status == "aborted"
    with open_run(outcome.path) as run:
        pressure = read_log(run, 1, "pressure")
    t, p = pressure.time_s, pressure.fields["value"]
    first = int(np.flatnonzero(p > 20.0)[0])
    emulator = outcome.rig.simulation.emulator
    grid = t[first:]
    volume = np.array([emulator.net_volume_ml(x) for x in grid])
    stopped_s = grid[np.flatnonzero(np.abs(volume - volume[-1]) > 1e-9)[-1] + 1]
    assert stopped_s <= t[first] + Timing.pressure_period_s
    assert np.all(np.diff(t) == pytest.approx(0.001))


def test_a_camera_slow_to_start_is_watched_from_its_first_frame(tmp_path):
    """A UVC webcam's first frame 0.8 s after the stream starts is no fault."""

    def slow_camera(rig):
        rig.simulation.capture.first_frame_s = 0.8

    outcome = run_sim(tmp_path, protocol(INFUSE, fps=10), prepare=slow_camera)
    assert (outcome.result.status, outcome.result.reason) == ("complete", "")
    with open_run(outcome.path) as run:
        assert len(read_log(run, 1, "length")) > 50


@pytest.mark.slow
@pytest.mark.parametrize(
    ("signame", "reason"),
    [
        ("SIGTERM", "stopped by SIGTERM (a service manager or kill)"),
        ("SIGHUP", "stopped: the terminal or SSH session was closed (SIGHUP)"),
    ],
)
def test_sigterm_and_sighup_stop_a_real_run(tmp_path, signame, reason):
    """``labrig run --sim`` in a subprocess, sent a real signal mid-infusion: the pump
    is stopped, the file finalised with the reason, the exit code 1."""
    protocol_path, out = tmp_path / "p.yaml", tmp_path / "run.h5"
    protocol_path.write_text(protocol("- infuse: {rate_ml_min: 6, volume_ml: 10}\n"))
    command = [sys.executable, "-m", "labrig", "run", str(protocol_path), "--sim", "--speed", "1"]
    process = subprocess.Popen(
        [*command, "--out", str(out)], stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True
    )
    try:
        poll_until(lambda: pressure_samples(out) > 200, "the run's first samples", timeout_s=120)
        process.send_signal(getattr(signal, signame))
        output, _ = process.communicate(timeout=120)
    finally:
        process.kill()
    assert process.returncode == 1, output
    assert f"reason: {reason}" in output
    with open_run(out) as run:
        assert run["entry/status"][()] == b"aborted"
        assert run["entry/reason"][()].decode() == reason
        pump = read_log(run, 1, "pump")
    # stopped within a second of the signal: far from the step's 100 s
    assert pump.fields["value"][-1] < 2.0


def pressure_samples(path) -> int:
    try:
        with open_run(path) as run:
            return len(read_log(run, 1, "pressure"))
    except (OSError, KeyError, InputError):  # not there yet, or being created
        return 0


def test_a_camera_that_never_starts_faults_the_run(tmp_path):
    """Watched from its first frame on, a camera that sends none is still caught."""

    def dead_camera(rig):
        rig.simulation.capture.first_frame_s = 60.0

    outcome = run_sim(tmp_path, protocol(INFUSE, fps=10), prepare=dead_camera)
    assert outcome.result.status == "faulted"
    assert outcome.result.reason.startswith("camera: ")
    assert plunger_still_after(outcome, outcome.end_s)


@pytest.mark.slow
def test_an_unconfirmed_stop_leads_the_cli_output(tmp_path, capsys, monkeypatch):
    """``labrig run``: the warning comes first once the run has ended, before the
    timing, the analysis and the status line."""
    import labrig.rig.assembly as assembly
    from labrig.cli import main

    build_rig = assembly.build_rig

    def stop_dies(protocol_, config):
        rig = build_rig(protocol_, config)
        rig.pump.timeout_s = 1.0  # the silence costs 1 s of host time, not 10 s
        rig.simulation.emulator.go_silent_at_stop()
        return rig

    monkeypatch.setattr(assembly, "build_rig", stop_dies)
    protocol_path = tmp_path / "p.yaml"
    protocol_path.write_text(protocol(INFUSE, max_kpa=20))
    with pytest.raises(SystemExit) as exited:
        main(["run", str(protocol_path), "--sim", "--out", str(tmp_path / "run.h5")])
    err = capsys.readouterr().err
    assert exited.value.code == 1
    warning = err.index(PUMP_STOP_NOT_CONFIRMED + "\n")
    assert warning < err.index("simulated ") < err.index("faulted: ")
