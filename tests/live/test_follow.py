"""``labrig.live.follow`` on run files written here, one state at a time (the file is
written by the real ``RunWriter`` in another process; no run, no timing)."""

from __future__ import annotations

import subprocess
import sys

import pytest
from support.liverun import PROTOCOL

from labrig.live.follow import FileFollower, open_growing, protocol_of
from labrig.live.session import run_info
from labrig.live.state import LiveState

# the writer runs in its own process, as it does under ``labrig watch`` (HDF5 refuses
# a reader and a writer of one file in one process with different locking)
WRITER = """
import sys
import numpy as np
from labrig.recording.run_writer import RunWriter

path, protocol, stage = sys.argv[1:]
writer = RunWriter(path, title="followed", protocol_text=open(protocol).read(),
                   protocol_path=protocol, rig_config_text="", repetitions=3,
                   with_length=False)
if stage == "between":
    writer.set_repetition_status(1, "running", t_start_s=0.0)
    t = np.arange(5.0)
    writer.append_pump(1, t, t * 0.5, t * 0.5, 0 * t, ["infusing"] * 5)
    writer.set_repetition_status(1, "complete", t_end_s=4.0)  # rep 2 still pending
if stage == "samples":  # samples seen before their repetition's status
    t = np.arange(5.0)
    writer.append_pump(1, t, t * 0.5, t * 0.5, 0 * t, ["infusing"] * 5)
writer.flush()
print("written", flush=True)
status, reason = sys.stdin.readline().split(maxsplit=1)
writer.finalise(status, "" if reason.strip() == "-" else reason.strip())  # "-": none
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


@pytest.mark.parametrize(
    ("stage", "seen", "repetition", "final", "reason"),
    [
        # opened between two repetitions: none running, yet the run is under way
        ("between", "running", 1, "complete", "-"),
        # the first samples read before the repetition's status: under way all the same
        ("samples", "running", 1, "complete", "-"),
        # opened before the first repetition: still starting
        ("before", "starting", 0, "aborted", "stopped by the operator"),
    ],
)
def test_a_watcher_sees_the_runs_status_from_the_file(
    tmp_path, stage, seen, repetition, final, reason
):
    path = tmp_path / f"{stage}.h5"
    writer = Writer(path, stage)
    follower = _follower(path)
    assert follower.poll() == "running"
    assert follower.state.status == seen
    assert follower.state._step.repetition == repetition
    writer.finalise(final, reason)
    assert follower.poll() == final
    assert follower.state.status == final
    assert follower.state.reason == ("" if reason == "-" else reason)
