"""Nothing overwritten, nothing truncated: the run file's lock against a second run,
``labrig recover`` and another program holding the file, all in real processes."""

import os
import subprocess
import sys
import textwrap
import threading

import h5py
import numpy as np
import pytest

from labrig.analysis.recovery import recover_run
from labrig.analysis.runfile import superblock_facts
from labrig.config.protocol import load_protocol
from labrig.config.rig_file import sim_rig_config
from labrig.errors import InputError
from labrig.recording.run_file_lock import (
    RunFileLock,
    claim_out_path,
    held_by_a_process,
    lock_path,
)
from labrig.recording.run_reader import open_run, read_log
from labrig.recording.run_writer import RunFileFailed, RunWriter
from labrig.rig.assembly import build_rig
from labrig.run.runner import Runner
from tests.support.simrig import short_protocol
from tests.support.simulated_runs import PROTOCOL, tiny_run

LIVE_WRITER = textwrap.dedent(
    """
    import sys, time
    import numpy as np
    from labrig.recording.run_writer import RunFileFailed, RunWriter
    writer = RunWriter(sys.argv[1], title="live", protocol_text=open(sys.argv[2]).read(),
                       protocol_path="tiny.yaml", rig_config_text="", repetitions=1,
                       with_length=False, flush_interval_s=0.05)
    writer.set_repetition_status(1, "running", t_start_s=0.0)
    writer.append_pressure(1, np.arange(10.0), np.zeros(10), np.zeros(10, bool))
    writer.flush()
    print("ready", flush=True)
    sys.stdin.readline()  # until the test lets go
    writer.finalise("complete")
    """
)

HOLDER = (
    "import h5py, sys; f = h5py.File(sys.argv[1], 'r'); print('ready', flush=True); "
    "sys.stdin.readline()"
)


@pytest.fixture
def live_run(tmp_path):
    """A run file another process is writing (in SWMR mode), and that process."""
    path = tmp_path / "live.h5"
    protocol = tmp_path / "tiny.yaml"
    protocol.write_text(PROTOCOL)
    process = subprocess.Popen(
        [sys.executable, "-c", LIVE_WRITER, str(path), str(protocol)],
        stdin=subprocess.PIPE,
        stdout=subprocess.PIPE,
        text=True,
    )
    assert process.stdout.readline().strip() == "ready"
    yield path, process
    if process.returncode is None:
        process.communicate("\n", timeout=60)


def make_writer(path):
    return RunWriter(
        path,
        title="second",
        protocol_text="name: second\n",
        protocol_path="second.yaml",
        rig_config_text="",
        repetitions=1,
        with_length=False,
    )


def test_a_second_writer_never_opens_a_live_file(live_run):
    path, process = live_run
    size = path.stat().st_size
    assert held_by_a_process(path)
    with pytest.raises(InputError, match=rf"pid {process.pid}\) is writing this file"):
        make_writer(path)
    with pytest.raises(InputError, match="is writing this file"):
        claim_out_path(path, overwrite=True)
    assert path.stat().st_size == size
    with open_run(path) as run:  # readers still follow it (SWMR read mode)
        assert len(read_log(run, 1, "pressure")) == 10
    process.communicate("\n", timeout=60)
    with open_run(path) as run:  # the first run closed its own file, whole
        assert run["entry/status"][()] == b"complete"
        assert len(read_log(run, 1, "pressure")) == 10
    assert not lock_path(path).exists() and not held_by_a_process(path)


def test_recover_refuses_a_live_file_and_changes_nothing(live_run):
    path, _ = live_run
    before = path.read_bytes()
    with pytest.raises(InputError, match="recover it once that has ended"):
        recover_run(path)
    assert path.read_bytes() == before
    assert superblock_facts(path)[1] != 0  # the writer's flag is still set
    with open_run(path) as run:
        assert run["entry/status"][()] == b"running"
        assert run["entry/repetitions/status"][0] == b"running"


def test_a_writer_never_replaces_an_existing_file(tmp_path):
    path = tiny_run(tmp_path / "done.h5")
    before = path.read_bytes()
    with pytest.raises(InputError, match="a file is already there"):
        make_writer(path)
    assert path.read_bytes() == before
    assert not lock_path(path).exists()


def test_a_file_put_at_the_path_before_the_run_makes_its_own_is_never_truncated(
    tmp_path, monkeypatch
):
    """Between the name's claim and HDF5's create, another program's file moved onto the
    path must come out as it went in: HDF5 creates only where nothing is."""
    path = tmp_path / "run.h5"
    theirs = tmp_path / "theirs.bin"
    theirs.write_bytes(b"another program's data")
    create_file = RunWriter._create_file

    def replaced_then_created(self):
        os.replace(theirs, path)
        return create_file(self)

    monkeypatch.setattr(RunWriter, "_create_file", replaced_then_created)
    with pytest.raises(InputError, match="a file is already there"):
        make_writer(path)
    assert path.read_bytes() == b"another program's data"
    assert not lock_path(path).exists()


def test_a_file_put_at_the_path_after_the_run_made_its_own_is_never_touched(tmp_path, monkeypatch):
    """Moved onto the path once the run's file exists, another program's file is
    neither written nor removed; the run says its own file is gone."""
    path = tmp_path / "run.h5"
    theirs = tmp_path / "theirs.bin"
    theirs.write_bytes(b"another program's data")
    hold_new_file = RunFileLock.hold_new_file

    def held_then_replaced(self, made_fd, refusal):
        hold_new_file(self, made_fd, refusal)
        os.replace(theirs, path)

    monkeypatch.setattr(RunFileLock, "hold_new_file", held_then_replaced)
    writer = make_writer(path)
    with pytest.raises(RunFileFailed, match="the run file is gone"):
        writer.finalise("complete")
    assert path.read_bytes() == b"another program's data"
    assert not lock_path(path).exists()


def test_a_file_held_open_elsewhere_is_never_touched(tmp_path):
    path = tiny_run(tmp_path / "held.h5")
    before = path.read_bytes()
    holder = subprocess.Popen(
        [sys.executable, "-c", HOLDER, str(path)],
        stdin=subprocess.PIPE,
        stdout=subprocess.PIPE,
        text=True,
    )
    try:
        assert holder.stdout.readline().strip() == "ready"
        with pytest.raises(InputError, match=r"already there.*--overwrite"):
            claim_out_path(path, overwrite=False)
        with pytest.raises(InputError, match="open in another program"):
            claim_out_path(path, overwrite=True)
        with pytest.raises(InputError, match="open in another program"):
            recover_run(path)
    finally:
        holder.communicate("\n", timeout=60)
    assert path.read_bytes() == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["held.h5"]


def test_overwrite_moves_the_old_run_and_its_video_aside(tmp_path):
    path = tiny_run(tmp_path / "run.h5")
    with h5py.File(path, "r+") as run:  # as a run with a video records it
        run["entry"].create_group("video").attrs["file"] = "run.avi"
    video = path.with_suffix(".avi")
    video.write_bytes(b"frames")

    lines = claim_out_path(path, overwrite=True)

    (moved,) = tmp_path.glob("run.replaced-*.h5")
    assert lines == [
        f"moved the old {path} to {moved}",
        f"moved the old {video} to {moved.with_suffix('.avi')}",
    ]
    assert not path.exists() and not video.exists()
    assert moved.with_suffix(".avi").read_bytes() == b"frames"
    with h5py.File(moved, "r") as run:
        assert run["entry/video"].attrs["file"] == moved.with_suffix(".avi").name
        assert run["entry/repetitions/rep_01/pressure/value"].shape == (4000,)
    # the same second again: the first moved file stays, the second gets a counter
    tiny_run(path)
    claim_out_path(path, overwrite=True)
    assert len(list(tmp_path.glob("run.replaced-*.h5"))) == 2


def test_a_killed_holder_leaves_no_lock_that_holds(tmp_path):
    path = tmp_path / "run.h5"
    lock_path(path).write_text("4242 run\n")  # the sidecar of a killed run
    assert not held_by_a_process(path)
    writer = make_writer(path)
    writer.append_pressure(1, np.arange(3.0), np.zeros(3), np.zeros(3, bool))
    writer.finalise("complete")
    assert not lock_path(path).exists()
    with RunFileLock(path, "recover").acquire("x"):
        assert lock_path(path).read_text().split()[1] == "recover"


def test_a_video_left_without_its_run_file_is_never_overwritten(tmp_path):
    path = tmp_path / "run.h5"
    video = path.with_suffix(".avi")
    video.write_bytes(b"frames")
    with pytest.raises(InputError, match=r"run.avi: a run's video is already there"):
        claim_out_path(path, overwrite=False)
    (line,) = claim_out_path(path, overwrite=True)
    (moved,) = tmp_path.glob("run.replaced-*.avi")
    assert line == f"moved the old {video} to {moved}"
    assert moved.read_bytes() == b"frames"


def test_a_writer_that_fails_to_lay_out_its_file_leaves_nothing(tmp_path):
    path = tmp_path / "run.h5"
    with pytest.raises(ValueError, match="NUL"):  # HDF5 strings hold no NUL
        RunWriter(
            path,
            title="a\0b",
            protocol_text="",
            protocol_path="p.yaml",
            rig_config_text="",
            repetitions=1,
            with_length=False,
        )
    assert list(tmp_path.iterdir()) == []
    make_writer(path).finalise("complete")  # the lock was let go


def test_a_run_refused_its_file_leaves_no_rig_running(live_run, tmp_path):
    """A run onto a file another process is writing is refused before anything moves,
    and its rig goes with it: no emulator, DAQ or camera thread left, the pty released."""
    path, process = live_run
    protocol_path = tmp_path / "run.yaml"
    protocol_path.write_text(short_protocol())
    loaded = load_protocol(protocol_path)
    threads_before = set(threading.enumerate())
    rig = build_rig(loaded.protocol, sim_rig_config())
    pty = rig.simulation.emulator.tty_path
    with pytest.raises(InputError, match=rf"pid {process.pid}\) is writing this file"):
        Runner(loaded, rig, path).run()
    assert threads_left(threads_before) == set()
    assert not os.path.exists(pty)


def threads_left(before: set[threading.Thread], settle_s: float = 5.0) -> set[str]:
    """The names of threads started since ``before`` that are still alive after waiting
    up to ``settle_s`` for each to end: a thread of the refused rig never ends, while a
    short-lived one another test's leftover started in this process meanwhile (a timer
    that fires and is gone) does not count against this rig."""
    new = set(threading.enumerate()) - before
    for thread in new:
        thread.join(timeout=settle_s / max(1, len(new)))
    return {thread.name for thread in new if thread.is_alive()}


@pytest.mark.parametrize("reach", ["symlink", "hardlink", "sidecar removed"])
def test_the_lock_belongs_to_the_file_not_its_name(live_run, reach):
    """A live run reached by another name, or with its sidecar removed: no recover, no
    second writer, no --overwrite moving it aside."""
    path, process = live_run
    if reach == "sidecar removed":
        lock_path(path).unlink()
        other = path
    else:
        other = path.with_name("other.h5")
        (other.symlink_to if reach == "symlink" else other.hardlink_to)(path)
    before = path.read_bytes()
    assert held_by_a_process(other)
    for attempt in (
        lambda: recover_run(other),
        lambda: claim_out_path(other, overwrite=True),
        lambda: make_writer(other),
    ):
        with pytest.raises(InputError, match="a labrig process"):
            attempt()
    assert path.read_bytes() == before
    process.communicate("\n", timeout=60)
    with open_run(path) as run:
        assert run["entry/status"][()] == b"complete"
