"""``labrig.live.follow`` on run files written here, one state at a time (the file is
written by the real ``RunWriter`` in another process; no run, no timing)."""

from __future__ import annotations

import subprocess
import sys

from liverun import PROTOCOL

from labrig.live.follow import FileFollower, open_growing, protocol_of
from labrig.live.session import run_info
from labrig.live.state import LiveState

# the writer runs in its own process, as it does under ``labrig watch`` (HDF5 refuses
# a reader and a writer of one file in one process with different locking)
WRITER = """
import sys
import numpy as np
from labrig.storage import RunWriter

path, protocol, stage = sys.argv[1:]
writer = RunWriter(path, title="followed", protocol_text=open(protocol).read(),
                   protocol_path=protocol, rig_config_text="", repetitions=3,
                   with_length=False)
if stage == "between":
    writer.set_repetition_status(1, "running", t_start_s=0.0)
    t = np.arange(5.0)
    writer.append_pump(1, t, t * 0.5, t * 0.5, 0 * t, ["infusing"] * 5)
    writer.set_repetition_status(1, "complete", t_end_s=4.0)  # rep 2 still pending
writer.flush()
print("written", flush=True)
status, reason = sys.stdin.readline().split(maxsplit=1)
writer.finalise(status, reason.strip())
"""


class Writer:
    def __init__(self, path, stage: str) -> None:
        self.proc = subprocess.Popen(
            [sys.executable, "-c", WRITER, str(path), str(PROTOCOL), stage],
            stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True,
        )  # fmt: skip
        assert self.proc.stdout.readline() == "written\n"

    def finalise(self, status: str, reason: str = "-") -> None:
        self.proc.stdin.write(f"{status} {reason}\n")
        self.proc.stdin.flush()
        assert self.proc.wait(60) == 0


def _follower(path) -> FileFollower:
    run = open_growing(path)
    protocol, title = protocol_of(run)
    return FileFollower(run, LiveState(run_info(protocol, title)), protocol)


def test_a_watcher_opening_the_file_between_repetitions_sees_the_run_running(tmp_path):
    path = tmp_path / "between.h5"
    writer = Writer(path, "between")
    follower = _follower(path)
    assert follower.poll() == "running"
    assert follower.state.status == "running"
    assert follower.state._step.repetition == 1
    writer.finalise("complete")
    assert follower.poll() == "complete"
    assert follower.state.status == "complete"


def test_a_watcher_of_a_file_before_its_first_repetition_sees_it_starting(tmp_path):
    path = tmp_path / "before.h5"
    writer = Writer(path, "before")
    follower = _follower(path)
    assert follower.poll() == "running"
    assert follower.state.status == "starting"
    writer.finalise("aborted", "stopped by the operator")
    assert follower.poll() == "aborted"
    assert follower.state.reason == "stopped by the operator"
