"""The fault soak: a short one through the command line, every fault kind once, and a
soak that catches a run made unsafe on purpose (its checks can fail)."""

import json
import subprocess
import sys

from labrig.rig import soak
from labrig.run.interlocks import PressureSignal


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
    result = json.loads(done.stdout)
    summary = result["summary"]
    n = len(soak.FAULTS)
    assert summary["safe"] == summary["runs"] == n
    assert summary["faults"] == dict.fromkeys(soak.FAULTS, 1)
    for run in result["runs"]:
        fault = soak.FAULTS[run["fault"]]
        assert run["status"] == fault.status and run["finalised"]
        assert run["samples_kept"] and run["frames_kept"]
        assert fault.reason in run["reason"]
        told = run["reason"].startswith("PUMP STOP NOT CONFIRMED: press Stop on the pump")
        assert told or run["stopped_after_s"] <= fault.stop_s
        assert told == fault.unconfirmed
    assert summary["line"].startswith(f"soak PASS: {n}/{n} runs safe (seed 5;")


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
