"""A run whose file disappears (its folder deleted) or cannot be written (a full disk,
a file size limit) stops the pump, says so in one line and never says "complete"; no
h5py traceback and no crash reach the operator, and the process ends with the error
exit status."""

import re
import resource
import shutil
import subprocess
import sys

import numpy as np
import pytest
from support.simrig import run_sim

from labrig.errors import InputError
from labrig.recording.run_writer import RunFileFailed
from tests.cli.test_run_out import TINY
from tests.recording.test_run_file_lock import make_writer
from tests.support.simulated_runs import tiny_run

# 50 s of 1 kHz pressure: a file that outgrows a small limit in its first seconds
INFUSE = TINY.replace("pressure_rate_hz: 100}", "pressure_rate_hz: 1000}").replace(
    "rate_ml_min: 60, volume_ml: 1", "rate_ml_min: 6, volume_ml: 5"
)


def test_a_writer_whose_file_is_removed_says_so(tmp_path):
    folder = tmp_path / "runs"
    folder.mkdir()
    writer = make_writer(folder / "r.h5")
    shutil.rmtree(folder)
    writer.append_pressure(1, np.arange(3.0), np.zeros(3), np.zeros(3, bool))
    gone = re.escape("r.h5: the run file is gone (removed, or its folder deleted, while the run")
    with pytest.raises(RunFileFailed, match=gone):
        writer.flush()
    with pytest.raises(RunFileFailed, match=gone):
        writer.finalise("complete")
    assert writer.closed


def test_a_run_whose_folder_is_deleted_is_faulted(tmp_path):
    folder = tmp_path / "runs"
    folder.mkdir()
    deleted = []

    def delete_once(rig):
        def tap(repetition, log, rows):
            if not deleted and log == "pressure":
                deleted.append(True)
                shutil.rmtree(folder)

        return tap

    outcome = run_sim(folder, INFUSE, tap=delete_once)
    assert outcome.result.status == "faulted"
    assert "the run file is gone" in outcome.result.reason
    assert outcome.pump_is_stopped()


@pytest.mark.slow  # a simulated run in a process of its own: ~5 s
def test_a_full_disk_is_one_line_and_no_crash(tmp_path):
    protocol = tmp_path / "p.yaml"
    protocol.write_text(INFUSE)
    limit = 200_000  # bytes: the run file reaches it in its first seconds

    def small_files():
        resource.setrlimit(resource.RLIMIT_FSIZE, (limit, limit))

    done = subprocess.run(
        [sys.executable, "-m", "labrig", "run", str(protocol), "--out", str(tmp_path / "r.h5")],
        capture_output=True,
        text=True,
        timeout=600,
        preexec_fn=small_files,
    )
    assert done.returncode == 1, done.stderr
    assert "Traceback" not in done.stderr and "internal error" not in done.stderr
    text = " ".join(done.stderr.split())
    assert "faulted: " in text and "complete:" not in text
    assert "cannot write the run file (File too large)" in text


def test_a_run_never_writes_over_a_video_left_there(tmp_path):
    video = tmp_path / "run.avi"
    video.write_bytes(b"frames of another run")
    text = INFUSE.replace(
        "pressure_rate_hz: 1000}", "pressure_rate_hz: 1000, camera_fps: 5, video: true}"
    )
    with pytest.raises(InputError, match=r"run\.avi: a run's video is already there"):
        run_sim(tmp_path, text)
    assert video.read_bytes() == b"frames of another run"
    assert not (tmp_path / "run.h5").exists()


def test_an_analysis_with_no_room_is_not_stored_and_the_file_unchanged(tmp_path):
    path = tiny_run(tmp_path / "r.h5")
    before = path.read_bytes()
    limit = len(before) + 1000  # bytes: the file may grow by less than an analysis

    def small_files():
        resource.setrlimit(resource.RLIMIT_FSIZE, (limit, limit))

    done = subprocess.run(
        [sys.executable, "-m", "labrig", "compare", str(path), "--store", "--json"],
        capture_output=True,
        text=True,
        timeout=600,
        preexec_fn=small_files,
    )
    assert (done.returncode, done.stderr) == (
        2,
        f"error: {path}: the analysis not stored: the process may not write files over "
        f"{limit} bytes (ulimit -f; the file is unchanged)\n",
    )
    assert path.read_bytes() == before
