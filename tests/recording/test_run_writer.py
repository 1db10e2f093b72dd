"""The run file: layout before the first sample, appends from threads, status, and a
SIGKILL of the writing process losing at most the last flush interval."""

import os
import signal
import subprocess
import sys
import textwrap
import threading
import time

import h5py
import numpy as np
import pytest

from labrig.errors import InputError
from labrig.recording.repair import clear_write_flag
from labrig.recording.run_reader import open_run, read_log, repetition_statuses
from labrig.recording.run_writer import RunWriter


def make_writer(path, repetitions=3, with_length=True):
    return RunWriter(
        path,
        title="test run",
        protocol_text="name: test\n",
        protocol_path="protocols/test.yaml",
        rig_config_text="rig: sim\n",
        repetitions=repetitions,
        with_length=with_length,
    )


def test_layout_exists_before_the_first_sample(tmp_path):
    path = tmp_path / "run.h5"
    writer = make_writer(path)
    with open_run(path) as run:  # a second reader while the writer is open (SWMR)
        entry = run["entry"]
        assert run.attrs["default"] == "entry"
        assert entry.attrs["NX_class"] == "NXentry"
        assert entry["protocol"][()].decode() == "name: test\n"
        assert entry["status"][()] == b"running"
        assert entry["pump_stop_confirmed"][()] == np.False_  # no stop confirmed yet
        for rep in ("rep_01", "rep_02", "rep_03"):
            for log, units in (("pressure", "kPa"), ("pump", "mL"), ("length", "mm")):
                group = entry["repetitions"][rep][log]
                assert group.attrs["NX_class"] == "NXlog"
                assert group["time"].attrs["units"] == "s"
                assert group["value"].attrs["units"] == units
                assert group["time"].shape == (0,)
        assert entry["versions/labrig"][()].decode()
    writer.finalise("complete")


def test_without_camera_there_is_no_length_log(tmp_path):
    writer = make_writer(tmp_path / "run.h5", with_length=False)
    with pytest.raises(ValueError, match="without a length"):
        writer.append_length(1, [0.0], [1.0], [0], [0], [1], [1], [True])
    with pytest.raises(ValueError, match="without a camera"):
        writer.set_measured_fps(30.0)
    writer.finalise("complete")
    with open_run(tmp_path / "run.h5") as run:
        assert "length" not in run["entry/repetitions/rep_01"]
        assert "camera" not in run["entry"]


def test_a_camera_that_gave_fewer_than_two_frames_has_no_measured_rate(tmp_path):
    writer = make_writer(tmp_path / "run.h5")
    writer.set_measured_fps(None)
    writer.finalise("aborted", "stopped at once")
    with open_run(tmp_path / "run.h5") as run:
        assert np.isnan(run["entry/camera/measured_fps"][()])


def test_concurrent_appends_round_trip(tmp_path):
    path = tmp_path / "run.h5"
    writer = make_writer(path, repetitions=2)
    blocks = 50

    def pressure():
        for k in range(blocks):
            t = np.arange(k * 100, (k + 1) * 100) / 1000.0
            writer.append_pressure(1, t, 10 * t, t > 4.0)

    def pump():
        for k in range(blocks):
            writer.append_pump(1, k * 0.1, k * 0.5, k * 0.5, 0.0, "infusing")

    threads = [threading.Thread(target=pressure), threading.Thread(target=pump)]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join()
    writer.set_repetition_status(1, "complete", t_start_s=0.0, t_end_s=5.0)
    writer.finalise("complete")

    with open_run(path) as run:
        p = read_log(run, 1, "pressure")
        np.testing.assert_allclose(p.time_s, np.arange(blocks * 100) / 1000.0)
        np.testing.assert_allclose(p.fields["value"], 10 * p.time_s)
        assert p.fields["out_of_range"].sum() == np.sum(p.time_s > 4.0)
        v = read_log(run, 1, "pump")
        np.testing.assert_allclose(v.fields["value"], np.arange(blocks) * 0.5)
        assert set(v.fields["state"]) == {b"infusing"}
        assert len(read_log(run, 2, "pressure")) == 0
        assert repetition_statuses(run) == [("complete", ""), ("pending", "")]
        assert run["entry/status"][()] == b"complete"


def test_finalise_marks_the_running_repetition_with_the_reason(tmp_path):
    path = tmp_path / "run.h5"
    writer = make_writer(path)
    writer.set_repetition_status(1, "complete")
    writer.set_repetition_status(2, "running")
    writer.finalise("faulted", "pump stalled at 31.2 kPa")
    writer.finalise("complete")  # idempotent: the first ending stands
    with open_run(path) as run:
        assert repetition_statuses(run) == [
            ("complete", ""),
            ("faulted", "pump stalled at 31.2 kPa"),
            ("pending", ""),
        ]
        assert run["entry/reason"][()] == b"pump stalled at 31.2 kPa"
        assert run["entry/end_time"][()]


def test_appending_after_close_is_an_error(tmp_path):
    writer = make_writer(tmp_path / "run.h5")
    writer.finalise("aborted", "Ctrl-C")
    with pytest.raises(RuntimeError, match="already closed"):
        writer.append_pressure(1, [0.0], [0.0], [False])


def test_missing_and_foreign_files_are_clear_errors(tmp_path):
    with pytest.raises(InputError, match="no such file"):
        open_run(tmp_path / "absent.h5")
    foreign = tmp_path / "foreign.h5"
    foreign.write_bytes(b"not hdf5 at all")
    with pytest.raises(InputError, match="not an HDF5 file"):
        open_run(foreign)
    with h5py.File(tmp_path / "other.h5", "w") as f:
        f["x"] = 1
    with open_run(tmp_path / "other.h5") as run, pytest.raises(InputError, match="missing entry"):
        read_log(run, 1, "pressure")


WRITER_SCRIPT = textwrap.dedent(
    """
    import sys, time
    import numpy as np
    from labrig.recording.run_writer import RunWriter
    writer = RunWriter(sys.argv[1], title="killed", protocol_text="name: k\\n",
                       protocol_path="k.yaml", rig_config_text="", repetitions=1,
                       with_length=False, flush_interval_s=0.5)
    print("ready", flush=True)
    while True:
        now = time.time()
        writer.append_pressure(1, np.full(10, now), np.zeros(10), np.zeros(10, bool))
        time.sleep(0.005)
    """
)


def test_sigkill_loses_at_most_one_second(tmp_path):
    path = tmp_path / "killed.h5"
    process = subprocess.Popen(
        [sys.executable, "-c", WRITER_SCRIPT, str(path)], stdout=subprocess.PIPE, text=True
    )
    assert process.stdout.readline().strip() == "ready"
    time.sleep(2.0)
    killed_at = time.time()
    os.kill(process.pid, signal.SIGKILL)
    process.wait()

    with pytest.raises(OSError):
        h5py.File(path, "r")  # the writer's flag is still set ...
    with open_run(path) as run:  # ... but labrig reads it
        t = read_log(run, 1, "pressure").time_s
        assert len(t) > 0
        assert killed_at - t[-1] <= 1.0
        assert run["entry/status"][()] == b"running"

    assert clear_write_flag(path) is True
    with h5py.File(path, "r+") as run:  # readable and writable by anything now
        assert run["entry/repetitions/rep_01/pressure/time"].shape[0] == len(t)
    assert clear_write_flag(path) is False


@pytest.mark.parametrize(
    ("data", "initval", "expected"),
    [  # the test vectors printed by lookup3.c's own driver
        (b"", 0, 0xDEADBEEF),
        (b"", 0xDEADBEEF, 0xBD5B7DDE),
        (b"Four score and seven years ago", 0, 0x17770551),
        (b"Four score and seven years ago", 1, 0xCD628161),
    ],
)
def test_lookup3_matches_the_reference_vectors(data, initval, expected):
    from labrig.recording.repair import lookup3

    assert lookup3(data, initval) == expected
