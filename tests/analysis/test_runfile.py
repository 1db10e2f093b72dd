"""Damaged, truncated, foreign and half-written run files: one clear line naming what
is missing, never a traceback; and the file a killed run leaves, recovered."""

import shutil

import h5py
import numpy as np
import pytest
from support.simulated_runs import PROTOCOL, tiny_run

from labrig.analysis import analyse, analyse_run
from labrig.analysis.recovery import recover_run
from labrig.analysis.runfile import load_run
from labrig.errors import InputError


def test_a_tiny_run_reads_and_analyses(tmp_path):
    result = analyse_run(tiny_run(tmp_path / "tiny.h5"))
    rep = result.repetitions[0]
    grid = result.grid_ml
    p, length = rep.p_kpa[1], rep.l_mm[1]
    assert np.isfinite(p).sum() >= len(grid) - 1
    np.testing.assert_allclose(p[np.isfinite(p)], 5.0 * grid[np.isfinite(p)], atol=1e-9)
    np.testing.assert_allclose(length[np.isfinite(length)], 30.0 + grid[np.isfinite(length)])
    assert result.comparison is None  # the protocol says compare_model: false


def test_not_hdf5_at_all(tmp_path):
    path = tmp_path / "notes.h5"
    path.write_text("pressure,volume\n1,2\n")
    with pytest.raises(InputError, match=r"not an HDF5 file \(no HDF5 signature"):
        load_run(path)


def test_missing_file(tmp_path):
    with pytest.raises(InputError, match="no such file"):
        load_run(tmp_path / "absent.h5")


def test_foreign_hdf5_names_the_missing_entry(tmp_path):
    path = tmp_path / "foreign.h5"
    with h5py.File(path, "w") as f:
        f["images/frame0"] = np.zeros((4, 4))
    with pytest.raises(
        InputError, match=r"not a labrig run file: missing /entry \(the file holds images\)"
    ):
        load_run(path)


def _remove(path, where):
    with h5py.File(path, "r+") as f:
        del f[where]


REP = "/entry/repetitions"


@pytest.mark.parametrize(
    ("removed", "message"),
    [
        (f"{REP}/rep_02", f"missing {REP}/rep_02 (the run lists 2 repetitions)"),
        (f"{REP}/rep_01/pump", f"missing {REP}/rep_01/pump"),
        (f"{REP}/rep_01/pressure/value", f"missing {REP}/rep_01/pressure/value"),
        (f"{REP}/status", f"missing {REP}/status"),
        ("/entry/protocol", "missing /entry/protocol"),
    ],
)
def test_a_missing_piece_is_named(tmp_path, removed, message):
    path = tiny_run(tmp_path / "damaged.h5")
    _remove(path, removed)
    with pytest.raises(InputError) as error:
        analyse(path)
    assert str(error.value) == f"{path}: {message}"


def test_a_field_of_the_wrong_length_is_named(tmp_path):
    path = tiny_run(tmp_path / "ragged.h5")
    with h5py.File(path, "r+") as f:
        values = f["entry/repetitions/rep_01/pump/value"]
        values.resize((values.shape[0] - 3,))
    with pytest.raises(InputError, match=r"rep_01/pump/value has 37 values for 40 times"):
        load_run(path)


def test_truncated_file_says_how_much_is_missing(tmp_path):
    whole = tiny_run(tmp_path / "whole.h5")
    size = whole.stat().st_size
    cut = tmp_path / "cut.h5"
    cut.write_bytes(whole.read_bytes()[: size - 5000])
    with pytest.raises(InputError) as error:
        load_run(cut)
    assert str(error.value).startswith(
        f"{cut}: truncated: {size - 5000} of the {size} bytes its header announces are present"
    )


def test_a_killed_run_is_readable_and_recovered(killed_file):
    killed_run = killed_file
    with pytest.raises(OSError):
        h5py.File(killed_run, "r")  # plain HDF5 refuses it ...
    record = load_run(killed_run)  # ... labrig reads what was flushed
    assert record.writer_flag_set
    assert record.status == "running"
    assert len(record.repetitions[0].pressure) > 0
    with pytest.raises(InputError, match=f"labrig recover {killed_run}"):
        analyse_run(killed_run)  # storing needs the file closed

    lines = recover_run(killed_run)
    assert lines[0] == f"{killed_run}: cleared the writer's 'open for writing' flag"
    assert f"{killed_run}: run status running -> aborted" in lines
    assert f"{killed_run}: repetition 1 running -> aborted" in lines
    assert lines[-1].startswith(f"{killed_run}: analysis stored (0 of 2 repetitions complete")
    with h5py.File(killed_run, "r") as f:  # any HDF5 tool opens it now
        assert f["entry/status"][()] == b"aborted"
        assert b"stopped without closing" in f["entry/reason"][()]
        assert "analysis" in f["entry"]
    assert not load_run(killed_run).writer_flag_set
    again = recover_run(killed_run)
    assert again == [f"{killed_run}: nothing to recover (closed by its writer, status aborted)"]


def test_recover_of_a_foreign_file_changes_nothing(tmp_path):
    path = tmp_path / "foreign.h5"
    with h5py.File(path, "w") as f:
        f["x"] = 1
    before = path.read_bytes()
    with pytest.raises(InputError, match="missing /entry"):
        recover_run(path)
    assert path.read_bytes() == before


def test_an_invalid_stored_protocol_is_named(tmp_path):
    path = tiny_run(tmp_path / "bad_protocol.h5")
    with h5py.File(path, "r+") as f:
        del f["entry/protocol"]
        f["entry/protocol"] = PROTOCOL.replace("max_volume_ml: 5", "max_volume_ml: -5")
    with pytest.raises(InputError, match=r"bad_protocol.h5:/entry/protocol.*max_volume_ml"):
        load_run(path)


def test_copying_keeps_a_run_analysable(tmp_path):
    path = tiny_run(tmp_path / "a.h5")
    shutil.copyfile(path, tmp_path / "b.h5")
    assert analyse(tmp_path / "b.h5").averaged == (1, 2)
