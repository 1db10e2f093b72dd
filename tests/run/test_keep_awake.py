"""System sleep blocked during a run where the system allows it, the lid switch too;
one clear line, and the run going on, where it does not. logind is played by a fake
``systemd-inhibit`` on PATH that records how it was called and grants or refuses the
lid switch as a polkit rule would."""

import logging
import os
import sys
import time

import pytest

from labrig.run import keep_awake

posix_only = pytest.mark.skipif(sys.platform == "win32", reason="the POSIX inhibitor commands")
# How long a test's inhibitor may take to refuse: a Python refusing took longer than the
# 0.2 s a real one is given on a busy host (load 9), and was taken to hold. A holding
# one is then known only after this long (it never exits), so only the tests of a
# refusal wait for it.
BUSY_HOST_REFUSAL_WAIT_S = 5.0
# How long a child Python may take to run its first line on a host busy enough to stall it.
CHILD_START_LIMIT_S = 60.0

# A systemd-inhibit that records its arguments, refuses what FAKE_LOGIND_REFUSES names
# (as logind answers a lock polkit does not allow), and otherwise runs the command it
# wraps (cat: it holds until its standard input closes).
FAKE_SYSTEMD_INHIBIT = """\
#!{python}
import os, subprocess, sys
args = sys.argv[1:]
with open(os.environ["FAKE_LOGIND_CALLS"], "a") as calls:
    calls.write(" ".join(args) + "\\n")
what = next(a for a in args if a.startswith("--what=")).split("=", 1)[1]
refused = os.environ.get("FAKE_LOGIND_REFUSES", "")
if refused and refused in what.split(":"):
    sys.exit("Failed to inhibit: Access denied")
sys.exit(subprocess.call(args[-1:]))
"""


@pytest.fixture
def logind(tmp_path, monkeypatch):
    """The fake systemd-inhibit first on PATH; returns the file of its calls."""
    bin_dir = tmp_path / "bin"
    bin_dir.mkdir()
    tool = bin_dir / "systemd-inhibit"
    tool.write_text(FAKE_SYSTEMD_INHIBIT.format(python=sys.executable))
    tool.chmod(0o755)
    calls = tmp_path / "calls"
    calls.touch()
    monkeypatch.setenv("PATH", f"{bin_dir}{os.pathsep}{os.environ['PATH']}")
    monkeypatch.setenv("FAKE_LOGIND_CALLS", str(calls))
    return calls


def whats(calls) -> list[str]:
    return [
        next(a for a in line.split() if a.startswith("--what="))
        for line in calls.read_text().splitlines()
    ]


@posix_only
def test_sleep_and_the_lid_switch_are_inhibited_for_the_block(logind, caplog):
    with caplog.at_level(logging.WARNING), keep_awake.system_kept_awake() as held:
        assert held
    assert whats(logind) == ["--what=sleep:idle:handle-lid-switch"]
    assert "--mode=block" in logind.read_text()
    assert caplog.records == []


@posix_only
def test_a_refused_lid_switch_lock_is_one_line_and_sleep_still_held(logind, caplog, monkeypatch):
    monkeypatch.setenv("FAKE_LOGIND_REFUSES", "handle-lid-switch")
    monkeypatch.setattr(keep_awake, "REFUSAL_WAIT_S", BUSY_HOST_REFUSAL_WAIT_S)
    with caplog.at_level(logging.WARNING), keep_awake.system_kept_awake() as held:
        assert held
    assert whats(logind) == ["--what=sleep:idle:handle-lid-switch", "--what=sleep:idle"]
    (record,) = caplog.records
    assert record.getMessage() == (
        "closing the laptop's lid will suspend the computer during this run "
        "(systemd-inhibit: Failed to inhibit: Access denied): keep it open"
    )


@posix_only
def test_an_inhibitor_is_held_for_the_block_and_released_after(monkeypatch, tmp_path):
    """A command that holds until its standard input closes (as systemd-inhibit's
    child does) runs for the block and ends after it."""
    marker = tmp_path / "held"
    script = f"import sys, pathlib; pathlib.Path({str(marker)!r}).touch(); sys.stdin.read()"
    command = [sys.executable, "-c", script]
    monkeypatch.setattr(keep_awake, "_inhibitor_commands", lambda: [(command, True)])
    with keep_awake.system_kept_awake() as held:
        assert held
        # The inhibitor is taken as holding once it has not refused within the refusal
        # wait, which can pass before a child Python on a busy host has run a line.
        started = time.monotonic()
        while not marker.exists() and time.monotonic() - started < CHILD_START_LIMIT_S:
            time.sleep(0.05)
        assert marker.exists()


@posix_only
def test_a_refused_inhibitor_is_one_warning_and_the_run_goes_on(monkeypatch, caplog):
    refusal = "import sys; sys.exit('Failed to connect to bus: No such file or directory')"
    command = [sys.executable, "-c", refusal]
    monkeypatch.setattr(
        keep_awake, "_inhibitor_commands", lambda: [(command, True), (command, False)]
    )
    monkeypatch.setattr(keep_awake, "REFUSAL_WAIT_S", BUSY_HOST_REFUSAL_WAIT_S)
    with caplog.at_level(logging.WARNING), keep_awake.system_kept_awake() as held:
        assert not held
    (record,) = caplog.records
    assert record.getMessage() == (
        f"system sleep is not blocked during this run ({os.path.basename(sys.executable)}: "
        "Failed to connect to bus: No such file or directory): keep the computer awake, "
        "and its lid open, until the run ends"
    )


@posix_only
def test_an_inhibitor_without_a_lid_lock_says_the_lid_will_suspend(monkeypatch, caplog):
    """caffeinate (macOS) keeps the system awake but not the lid's switch."""
    command = [sys.executable, "-c", "import sys; sys.stdin.read()"]
    monkeypatch.setattr(keep_awake, "_inhibitor_commands", lambda: [(command, False)])
    with caplog.at_level(logging.WARNING), keep_awake.system_kept_awake() as held:
        assert held
    (record,) = caplog.records
    assert record.getMessage().startswith("closing the laptop's lid will suspend the computer")


@posix_only
def test_no_inhibitor_at_all_is_said(monkeypatch, caplog):
    monkeypatch.setattr(keep_awake.shutil, "which", lambda name: None)
    with caplog.at_level(logging.WARNING), keep_awake.system_kept_awake() as held:
        assert not held
    assert "no systemd-inhibit or caffeinate on this system" in caplog.text
