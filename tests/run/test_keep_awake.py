"""System sleep blocked during a run where the system allows it; one clear line, and
the run going on, where it does not."""

import logging
import os
import sys

import pytest

from labrig.run import keep_awake


@pytest.mark.skipif(sys.platform == "win32", reason="the POSIX inhibitor commands")
def test_an_inhibitor_is_held_for_the_block_and_released_after(monkeypatch, tmp_path):
    """A command that holds until its standard input closes (as systemd-inhibit's
    child does) runs for the block and ends after it."""
    marker = tmp_path / "held"
    script = f"import sys, pathlib; pathlib.Path({str(marker)!r}).touch(); sys.stdin.read()"
    monkeypatch.setattr(keep_awake, "_inhibitor_command", lambda: [sys.executable, "-c", script])
    with keep_awake.system_kept_awake() as held:
        assert held
    assert marker.exists()


@pytest.mark.skipif(sys.platform == "win32", reason="the POSIX inhibitor commands")
def test_a_refused_inhibitor_is_one_warning_and_the_run_goes_on(monkeypatch, caplog):
    refusal = "import sys; sys.exit('Failed to connect to bus: No such file or directory')"
    monkeypatch.setattr(keep_awake, "_inhibitor_command", lambda: [sys.executable, "-c", refusal])
    with caplog.at_level(logging.WARNING), keep_awake.system_kept_awake() as held:
        assert not held
    (record,) = caplog.records
    assert record.getMessage() == (
        f"system sleep is not blocked during this run ({os.path.basename(sys.executable)}: "
        "Failed to connect to bus: No such file or directory): keep the computer awake "
        "until the run ends"
    )


@pytest.mark.skipif(sys.platform == "win32", reason="the POSIX inhibitor commands")
def test_no_inhibitor_at_all_is_said(monkeypatch, caplog):
    monkeypatch.setattr(keep_awake.shutil, "which", lambda name: None)
    with caplog.at_level(logging.WARNING), keep_awake.system_kept_awake() as held:
        assert not held
    assert "no systemd-inhibit or caffeinate on this system" in caplog.text
