"""The fault soak: every fault kind once through the command line (-m soak), one run
through the command in this process, and a soak that catches a run made unsafe on
purpose (its checks can fail)."""

import json
import logging
import subprocess
import sys

import pytest

from labrig.cli import main
from labrig.rig import soak
from labrig.run.interlocks import PressureSignal


# outside the default run (-m soak): each fault kind's safe ending is the default run's in
# tests/rig/test_device_deaths.py, test_faults.py, test_pump_as_found_run.py,
# tests/run/test_endings.py, test_interlocks.py and test_signals_end_the_process.py, the
# command's JSON and verdicts in test_one_soak_run_through_the_command below
@pytest.mark.soak
def test_a_short_soak_is_safe_for_every_fault_kind():
    done = subprocess.run(
        [
            sys.executable,
            "-m",
            "labrig",
            "rig",
            "soak",
            "--sim",
            "--runs",
            str(len(soak.FAULTS)),
            "--seed",
            "5",
            "--json",
        ],
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert done.returncode == 0, done.stdout[-2000:] + done.stderr[-2000:]
    _assert_every_run_safe(json.loads(done.stdout), list(soak.FAULTS), seed=5)


def test_one_soak_run_through_the_command(capsys):
    """``labrig rig soak --sim --json`` in this process: seed 7's one run cuts the sensor
    wire (a floating input), and the soak finds it safe."""
    labrig_logger = logging.getLogger("labrig")
    level = labrig_logger.level  # the command quietens labrig's warnings: restored after
    try:
        with pytest.raises(SystemExit) as exited:
            main(["rig", "soak", "--sim", "--runs", "1", "--seed", "7", "--json"])
    finally:
        labrig_logger.setLevel(level)
    out, err = capsys.readouterr()
    assert exited.value.code == 0, out[-2000:] + err[-2000:]
    _assert_every_run_safe(json.loads(out), ["floating-wire"], seed=7)


def _assert_every_run_safe(result, kinds, seed):
    """The soak's JSON: one safe run for each of ``kinds``, each ended as its fault says."""
    summary = result["summary"]
    n = len(kinds)
    assert summary["safe"] == summary["runs"] == n
    assert summary["faults"] == dict.fromkeys(kinds, 1)
    for run in result["runs"]:
        fault = soak.FAULTS[run["fault"]]
        assert run["status"] == fault.status and run["finalised"]
        assert run["samples_kept"] and run["frames_kept"]
        assert fault.reason in run["reason"]
        told = run["reason"].startswith("PUMP STOP NOT CONFIRMED: press Stop on the pump")
        assert told or run["stopped_after_s"] <= fault.stop_s
        assert told == fault.unconfirmed
    assert summary["line"].startswith(f"soak PASS: {n}/{n} runs safe (seed {seed};")


def test_the_soak_needs_the_simulated_rig():
    done = subprocess.run(
        [sys.executable, "-m", "labrig", "rig", "soak", "--runs", "1"],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert done.returncode == 2
    assert "simulated rig only: add --sim" in done.stderr
    assert "Traceback" not in done.stderr


def test_a_run_without_the_signal_interlock_is_found_unsafe(monkeypatch):
    """With the dead-sensor interlock switched off, a cut Vout wire lets the pump infuse
    to the target: the soak says so, and fails."""
    monkeypatch.setattr(PressureSignal, "check_pressure", lambda self, block: None)
    monkeypatch.setattr(soak, "fault_plan", lambda runs, seed: [("sensor-vout-cut", 3.0)])
    summary, verdicts = soak.soak(1, seed=0)
    assert not summary.ok and summary.safe == 0
    problems = " ".join(verdicts[0].problems)
    assert "ended complete" in problems
    assert "the plunger moved until" in problems
    assert summary.line().startswith("soak FAIL: 0/1 runs safe")
