"""``labrig show | plot | export | compare | recover`` through the real entry point."""

import csv

import h5py
import numpy as np
import pytest

from labrig.analysis import analyse, analyse_run
from labrig.analysis.curves import DEFLATE, INFLATE
from labrig.cli import main
from labrig.recording.run_reader import open_run, read_log


def run(argv, capsys):
    with pytest.raises(SystemExit) as exited:
        main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return exited.value.code, out, err


def test_show_tables_metadata_protocol_and_repetitions(segment_run, capsys):
    code, out, err = run(["show", segment_run.path], capsys)
    assert code == 0, err
    assert "simulated SI-B46-T20" in out
    assert "repeat x5" in out and "infuse rate_ml_min 20, volume_ml 20.8" in out
    assert "repetition 3 faulted: simulated fault" in out
    table = out[out.index("repetitions (") :].splitlines()
    header = next(k for k, line in enumerate(table) if line.split()[:2] == ["#", "status"])
    rows = {line.split()[0]: line.split() for line in table[header + 2 : header + 7]}
    assert rows["1"][:3] == ["1", "complete", "yes"]
    assert rows["3"][:2] == ["3", "faulted"] and rows["3"][2] != "yes"
    assert [rows[k][1] for k in "1245"] == ["complete"] * 4
    assert "no stored analysis; computed now, not stored" in out


def test_show_uses_the_stored_analysis(segment_run, copy_of, capsys):
    path = copy_of(segment_run)
    analyse_run(path)
    code, out, _ = run(["show", path], capsys)
    assert code == 0
    assert "no stored analysis" not in out
    assert "RMSE of the mean against the model (SI-B46-T20)" in out


def test_plot_writes_a_png(snap_run, tmp_path, capsys):
    import matplotlib.image

    pytest.importorskip("labrig.model.actuator.path", reason="the actuator path solver")
    out_png = tmp_path / "fig2c.png"
    code, out, _ = run(["plot", snap_run.path, "-o", out_png], capsys)
    assert code == 0
    assert out_png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    image = matplotlib.image.imread(out_png)
    assert image.shape[0] > 800 and image.shape[1] > 800
    assert image[..., :3].std() > 0.05  # not a blank canvas
    assert f"{out_png}: p-v and l-v" in out


def test_plot_into_a_missing_folder_is_refused(snap_run, tmp_path, capsys):
    code, _, err = run(["plot", snap_run.path, "-o", tmp_path / "nope" / "a.png"], capsys)
    assert code == 2
    assert (
        err.strip() == f"error: -o {tmp_path}/nope/a.png: the folder {tmp_path}/nope does not exist"
    )


def _read_csv(path):
    with open(path, newline="") as handle:
        rows = list(csv.reader(handle))
    header, body = rows[0], rows[1:]
    return header, {name: [row[k] for row in body] for k, name in enumerate(header)}


def test_export_round_trips_raw_and_averaged_series(tiny_file, tmp_path, capsys):
    out_dir = tmp_path / "csv"
    code, out, _ = run(["export", tiny_file, "--csv", out_dir], capsys)
    assert code == 0
    header, pressure = _read_csv(out_dir / "rep_02_pressure.csv")
    assert header == ["time_s", "pressure_kpa", "out_of_range", "volume_ml"]
    with open_run(tiny_file) as f:
        raw = read_log(f, 2, "pressure")
        pump = read_log(f, 2, "pump")
    np.testing.assert_array_equal(np.array(pressure["time_s"], float), raw.time_s)
    np.testing.assert_array_equal(np.array(pressure["pressure_kpa"], float), raw.fields["value"])
    assert set(pressure["out_of_range"]) == {"0"}
    header, pump_csv = _read_csv(out_dir / "rep_02_pump.csv")
    assert header == ["time_s", "volume_ml", "infused_ml", "withdrawn_ml", "state"]
    np.testing.assert_array_equal(np.array(pump_csv["volume_ml"], float), pump.fields["value"])
    assert set(pump_csv["state"]) == {"infusing"}
    header, _ = _read_csv(out_dir / "rep_01_length.csv")
    assert header == ["time_s", "length_mm", "x1_px", "y1_px", "x2_px", "y2_px", "ok"]

    result = analyse(tiny_file)
    for phase, name in ((INFLATE, "inflate"), (DEFLATE, "deflate")):
        header, curves = _read_csv(out_dir / f"curves_{name}.csv")
        assert header[0] == "volume_ml" and "mean_pressure_kpa" in header
        np.testing.assert_array_equal(np.array(curves["volume_ml"], float), result.grid_ml)
        np.testing.assert_array_equal(
            np.array(curves["mean_pressure_kpa"], float), result.mean_p[phase].mean
        )
        np.testing.assert_array_equal(
            np.array(curves["rep_02_length_mm"], float), result.repetitions[1].l_mm[phase]
        )
    assert f"{out_dir}: 9 CSV files" in out  # 2 x 3 logs, 2 curves, transitions; no model


def test_compare_against_the_specimen_and_against_other_segments(segment_run, copy_of, capsys):
    code, out, _ = run(["compare", segment_run.path], capsys)
    assert code == 0
    line = next(s for s in out.splitlines() if s.strip().startswith("inflate"))
    own = float(line.split()[1])
    assert 0.3 < own < 0.55  # the inlet's R Q and the residual offset, see test_compare
    assert "none predicted, none measured" in out

    code, out, _ = run(["compare", segment_run.path, "--segments", "SI-B46-T22"], capsys)
    assert code == 0
    assert "against the model (SI-B46-T22)" in out
    line = next(s for s in out.splitlines() if s.strip().startswith("inflate"))
    assert float(line.split()[1]) > 2 * own  # another segment fits worse

    path = copy_of(segment_run)
    code, out, _ = run(["compare", path, "--segments", "SI-B46-T22", "--store"], capsys)
    assert code == 0 and f"stored in {path}" in out
    with h5py.File(path, "r") as f:
        assert f["entry/analysis/model/segments"][()].tolist() == [b"SI-B46-T22"]


def test_compare_with_an_unknown_segment_is_one_line(segment_run, capsys):
    code, _, err = run(["compare", segment_run.path, "--segments", "SI-B99-T99"], capsys)
    assert code == 2
    assert err.startswith("error: unknown segment 'SI-B99-T99'")
    assert len(err.strip().splitlines()) == 1


def test_compare_a_library_actuator(library_run, capsys):
    pytest.importorskip("labrig.model.actuator.path", reason="the actuator path solver")
    code, out, _ = run(["compare", library_run.path], capsys)
    assert code == 0
    snaps = [s.split() for s in out.splitlines() if "snap (" in s]
    assert [row[0] for row in snaps] == ["inflate", "deflate"]
    for row in snaps:
        v_model, v_measured = float(row[3]), float(row[4])
        assert abs(v_model - v_measured) < 0.6


def test_recover_a_killed_run(killed_file, capsys):
    code, out, err = run(["recover", killed_file], capsys)
    assert code == 0, err
    assert f"{killed_file}: cleared the writer's 'open for writing' flag" in out
    assert "run status running -> aborted" in out
    with h5py.File(killed_file, "r") as f:
        assert "analysis" in f["entry"]
    code, out, _ = run(["recover", killed_file], capsys)
    assert code == 0 and "nothing to recover" in out


def test_show_a_killed_run_warns_and_shows_what_was_flushed(killed_file, capsys):
    code, out, _ = run(["show", killed_file], capsys)
    assert code == 0
    assert "no process writes it (its run was killed)" in out and "labrig recover" in out
    assert "running" in out


@pytest.mark.parametrize("command", ["show", "plot", "export", "compare", "recover"])
def test_damaged_files_give_one_line_and_exit_2(command, tiny_file, tmp_path, capsys):
    foreign = tmp_path / "foreign.h5"
    with h5py.File(foreign, "w") as f:
        f["x"] = 1
    truncated = tmp_path / "truncated.h5"
    truncated.write_bytes(tiny_file.read_bytes()[:-4000])
    missing_rep = tmp_path / "missing.h5"
    missing_rep.write_bytes(tiny_file.read_bytes())
    with h5py.File(missing_rep, "r+") as f:
        del f["entry/repetitions/rep_02"]
    text = tmp_path / "text.h5"
    text.write_text("not a run\n")
    extra = {"plot": ["-o", tmp_path / "x.png"], "export": ["--csv", tmp_path / "csv"]}
    expected = {
        foreign: "not a labrig run file: missing /entry",
        truncated: "truncated:",
        missing_rep: "missing /entry/repetitions/rep_02",
        text: "not an HDF5 file",
    }
    for path, message in expected.items():
        code, _, err = run([command, path, *extra.get(command, [])], capsys)
        assert code == 2, (command, path, err)
        assert err.startswith(f"error: {path}: ") and message in err
        assert len(err.strip().splitlines()) == 1 and "Traceback" not in err
