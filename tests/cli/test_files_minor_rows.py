"""The small ways a file or a path went wrong: a link left where an old run is moved
aside, a recover cut short, a path that is not UTF-8, one damaged file among a
campaign's."""

import importlib
import json
import os
import shutil

import h5py
import pytest

from labrig.analysis import recovery
from labrig.analysis.recovery import recover_run
from labrig.cli import main
from labrig.recording.run_file_lock import replaced_path
from tests.support.simulated_runs import PROTOCOL, killed_run, tiny_run


def run(argv, capsys):
    with pytest.raises(SystemExit) as exited:
        main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return exited.value.code, out, err


def test_a_dangling_link_at_the_moved_aside_name_is_kept(tmp_path):
    path = tmp_path / "run.h5"
    taken = tmp_path / "run.replaced-20260101-000000.h5"
    taken.symlink_to(tmp_path / "nowhere.h5")  # dangling
    assert replaced_path(path, "20260101-000000") == tmp_path / (
        "run.replaced-20260101-000000-2.h5"
    )


def test_a_recover_cut_short_is_finished_by_the_next(tmp_path, monkeypatch):
    path = killed_run(tmp_path)

    def cut_short(*args, **kwargs):
        raise KeyboardInterrupt  # Ctrl-C after the file was closed, before the analysis

    with monkeypatch.context() as patched:
        patched.setattr(
            importlib.import_module("labrig.analysis.analyse"), "analyse_run", cut_short
        )
        with pytest.raises(KeyboardInterrupt):
            recover_run(path)
    with h5py.File(path, "r") as f:
        assert f["entry/reason"][()].decode().startswith(recovery.RECOVERED)
        assert "entry/analysis" not in f
    lines = recover_run(path)
    assert len(lines) == 1 and "analysis stored" in lines[0]
    with h5py.File(path, "r") as f:
        assert "entry/analysis" in f
    assert "nothing to recover" in recover_run(path)[0]


def test_a_protocol_path_that_is_not_utf8_is_recorded(tmp_path, capsys):
    name = os.fsdecode(b"tiny\xff.yaml")  # a byte no UTF-8 name holds
    protocol = tmp_path / name
    protocol.write_text(PROTOCOL)
    out = tmp_path / "r.h5"
    code, _, err = run(["run", protocol, "--sim", "--out", out], capsys)
    assert (code, "internal error" in err) == (0, False)
    with h5py.File(out, "r") as f:
        assert f["entry/protocol"].attrs["source_file"].endswith("tiny\\xff.yaml")


def test_one_damaged_file_is_a_row_not_the_end_of_the_table(tmp_path, capsys):
    good = tiny_run(tmp_path / "a.h5")
    bad = tmp_path / "b.h5"
    shutil.copyfile(good, bad)
    data = bytearray(bad.read_bytes())
    data[4000:6048] = bytes(2048)
    bad.write_bytes(bytes(data))
    code, out, _ = run(["runs", tmp_path, "--json"], capsys)
    assert code == 0
    rows = {os.path.basename(row["file"]): row for row in json.loads(out)["runs"]}
    assert rows["a.h5"]["status"] == "complete" and rows["a.h5"]["error"] is None
    assert rows["b.h5"]["error"].startswith(f"{bad}: damaged: ")
