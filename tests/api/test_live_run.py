"""``labrig.open_run`` on a run being recorded by another process (a real SWMR writer)."""

import subprocess
import sys
import textwrap

import numpy as np
import pytest

import labrig
from labrig.analysis.runfile import writer_flag_set

# RunWriter as the runner uses it: layout, SWMR, then appends flushed every 50 ms; it
# reports each flush's row count on stdout. On SIGUSR1 it ends the run as the runner
# does: finalises the file, then reopens it for writing (where the analysis is stored)
WRITER = textwrap.dedent(
    """
    import signal, sys, time
    import h5py
    import numpy as np
    from labrig.recording.run_writer import RunWriter
    ending = []
    signal.signal(signal.SIGUSR1, lambda *_: ending.append(True))
    protocol = open(sys.argv[2]).read()
    writer = RunWriter(sys.argv[1], title="live", protocol_text=protocol,
                       protocol_path="tiny.yaml", rig_config_text="", repetitions=2,
                       with_length=False, flush_interval_s=0.05)
    writer.set_repetition_status(1, "running", t_start_s=0.0)
    k = 0
    while not ending:
        t = k * 0.1 + np.arange(100) * 1e-3
        writer.append_pressure(1, t, 50.0 * t, np.zeros(100, bool))
        writer.append_pump(1, k * 0.1, 10.0 * k * 0.1, 10.0 * k * 0.1, 0.0, "infusing")
        writer.flush()
        k += 1
        print(k * 100, flush=True)
        time.sleep(0.01)
    writer.finalise("complete")
    with h5py.File(sys.argv[1], "r+") as h5:
        h5["entry"].attrs["reopened"] = True
    print("reopened", flush=True)
    """
)


@pytest.fixture
def live_writer(tmp_path):
    from support.simulated_runs import PROTOCOL

    path = tmp_path / "live.h5"
    (tmp_path / "tiny.yaml").write_text(PROTOCOL)
    process = subprocess.Popen(
        [sys.executable, "-c", WRITER, str(path), str(tmp_path / "tiny.yaml")],
        stdout=subprocess.PIPE,
        text=True,
    )
    process.stdout.readline()  # the first flush is on disk
    yield path, process
    process.kill()
    process.wait()
    process.stdout.close()


def _rows_after(process, rows: int) -> None:
    """Wait (on the writer's word, not a clock) until it has flushed past ``rows``."""
    while int(process.stdout.readline()) <= rows:
        pass


def test_a_live_run_is_read_as_far_as_written_and_flagged(live_writer):
    path, process = live_writer
    with pytest.warns(labrig.RunOpenWarning, match="being recorded"):
        first = labrig.open_run(path)
    assert first.live and first.writer_open and first.status == "running"
    n_first = int(first.repetitions.loc[1, "n_pressure"])
    assert n_first >= 100 and n_first % 100 == 0
    data = first.raw(1)
    assert data.sizes["time"] == n_first
    np.testing.assert_allclose(data["value"].values, 50.0 * data["time"].values)

    _rows_after(process, n_first)
    with pytest.warns(labrig.RunOpenWarning):
        later = labrig.open_run(path)
    more = later.raw(1)
    assert more.sizes["time"] > n_first
    # the first reading is the start of the later one: nothing rewritten, nothing lost
    np.testing.assert_array_equal(more["time"].values[:n_first], data["time"].values)
    # the data so far, analysed in memory (5 kPa/mL on the way up)
    table = later.curves_table("inflate").dropna(subset=["rep_01_pressure_kpa"])
    np.testing.assert_allclose(table["rep_01_pressure_kpa"], 5 * table["volume_ml"], atol=0.1)
    assert process.poll() is None  # the writer kept writing through all of it
    _rows_after(process, more.sizes["time"])
    assert writer_flag_set(path)


def test_reading_never_blocks_the_writer_reopening_its_file(live_writer):
    """The runner reopens its file (mode r+) to store the analysis once the run ends;
    a reader holding HDF5's file lock would make that fail."""
    import signal

    path, process = live_writer
    with pytest.warns(labrig.RunOpenWarning):
        run = labrig.open_run(path)
    n = run.raw(1).sizes["time"]
    assert n > 0 and run.curves_table().shape[0] > 0  # the reads are done, run is kept
    process.send_signal(signal.SIGUSR1)
    assert process.stdout.read().split()[-1] == "reopened"
    assert process.wait() == 0
    after = labrig.open_run(path)
    assert after.complete and not after.writer_open and not after.live
    assert after.raw(1).sizes["time"] >= n
