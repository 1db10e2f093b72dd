"""``labrig.open_run``: a run file read lazily, read-only, as xarray and pandas."""

import csv
import hashlib
import math
import os
import warnings

import h5py
import numpy as np
import pytest
from support.api_runs import cli

import labrig
from labrig.analysis.runfile import writer_flag_set
from labrig.errors import InputError


def test_opening_reads_the_metadata_and_the_sizes(tiny_file):
    run = labrig.open_run(tiny_file)
    assert run.status == "complete" and run.complete and not run.writer_open and not run.live
    assert run.title == "tiny" and run.protocol.name == "tiny"
    assert run.metadata["specimen"] == ["SI-B46-T20"]
    reps = run.repetitions
    assert list(reps.index) == [1, 2] and list(reps["status"]) == ["complete"] * 2
    with h5py.File(tiny_file, "r") as h5:
        for log in ("pressure", "pump", "length"):
            sizes = [len(h5[f"entry/repetitions/rep_0{i}/{log}/time"]) for i in (1, 2)]
            assert list(reps[f"n_{log}"]) == sizes


def test_a_raw_series_is_the_files_nxlog_with_its_units(tiny_file):
    data = labrig.open_run(tiny_file).raw(2, "pressure")
    with h5py.File(tiny_file, "r") as h5:
        group = h5["entry/repetitions/rep_02/pressure"]
        np.testing.assert_array_equal(data["time"].values, group["time"][:])
        np.testing.assert_array_equal(data["value"].values, group["value"][:])
        assert data["value"].attrs["units"] == group["value"].attrs["units"] == "kPa"
    assert data["time"].attrs["units"] == "s"
    assert data["value"].attrs["nexus_path"] == "/entry/repetitions/rep_02/pressure/value"
    assert data.sizes["time"] == 4000


def test_a_time_window_reads_only_its_rows(tiny_file):
    run = labrig.open_run(tiny_file)
    whole = run.raw(1, "pressure")
    t = whole["time"].values
    for start, stop in ((1.0, 2.0), (0.0005, 0.0025), (None, 0.5), (3.5, None), (9.0, 10.0)):
        part = run.raw(1, "pressure", start_s=start, stop_s=stop)
        keep = (t >= (-math.inf if start is None else start)) & (
            t < (math.inf if stop is None else stop)
        )
        np.testing.assert_array_equal(part["time"].values, t[keep])
        np.testing.assert_array_equal(part["value"].values, whole["value"].values[keep])


def test_bad_requests_are_one_line_errors(tiny_file, tmp_path):
    run = labrig.open_run(tiny_file)
    with pytest.raises(InputError, match="repetition 3: the run has 1 to 2"):
        run.raw(3)
    with pytest.raises(InputError, match="has no 'force' log"):
        run.raw(1, "force")
    for wrong in ("2", 1.0, True):
        with pytest.raises(InputError, match=f"repetition {wrong!r}: a whole number, 1 to 2"):
            run.raw(wrong)
    assert labrig.InputError is InputError  # a notebook catches it from labrig itself
    with pytest.raises(InputError, match="no comparison with the model"):
        run.comparison  # noqa: B018
    with pytest.raises(InputError, match="no such file"):
        labrig.open_run(tmp_path / "missing.h5")
    (tmp_path / "text.h5").write_text("not hdf5")
    with pytest.raises(InputError, match="not an HDF5 file"):
        labrig.open_run(tmp_path / "text.h5")
    with h5py.File(tmp_path / "foreign.h5", "w") as h5:
        h5["entry/title"] = "someone else's"
    with pytest.raises(InputError, match=r"foreign\.h5: missing /entry/repetitions"):
        labrig.open_run(tmp_path / "foreign.h5")


def _csv(path):
    with open(path, newline="") as handle:
        rows = list(csv.DictReader(handle))
    return {name: [row[name] for row in rows] for name in rows[0]}


def _assert_same(frame, columns):
    """A DataFrame against CSV text columns: same names, same numbers."""
    assert list(frame.columns) == list(columns)
    for name, texts in columns.items():
        values = frame[name].to_numpy()
        if values.dtype.kind == "b":
            values = values.astype(int)
        if values.dtype.kind in "iuf":
            np.testing.assert_array_equal(values.astype(float), np.array(texts, float), name)
        else:
            assert list(values.astype(str)) == texts, name


def test_tables_are_what_export_writes(quick_run, tmp_path, capsys):
    code, _, err = cli(["export", quick_run, "--csv", tmp_path], capsys)
    assert code == 0, err
    run = labrig.open_run(quick_run)
    for log in ("pressure", "pump", "length"):
        _assert_same(run.raw_table(2, log), _csv(tmp_path / f"rep_02_{log}.csv"))
    written = _csv(tmp_path / "curves_deflate.csv")
    _assert_same(run.curves_table("deflate")[list(written)], written)
    # the file's direction (+1/-1) is the table's direction_sign, named beside it
    transitions = run.transitions
    assert set(transitions["direction"]) <= {"inflate", "deflate"}
    assert list(transitions["direction"] == "inflate") == list(transitions["direction_sign"] > 0)
    as_file = transitions.drop(columns=["direction", "time_s"])
    as_file = as_file.rename(columns={"direction_sign": "direction"})
    _assert_same(as_file, _csv(tmp_path / "transitions.csv"))


def test_the_curves_dataset_holds_the_analysis(quick_run):
    run = labrig.open_run(quick_run)
    curves = run.curves
    assert curves.sizes == {"repetition": 2, "phase": 2, "volume_ml": len(run.analysis.grid_ml)}
    assert curves["volume_ml"].attrs["units"] == "mL"
    assert curves["mean_pressure_kpa"].attrs["units"] == "kPa"
    table = run.curves_table("inflate")
    for name in ("mean_pressure_kpa", "std_length_mm", "model_pressure_kpa"):
        np.testing.assert_array_equal(curves[name].sel(phase="inflate").values, table[name])
    np.testing.assert_array_equal(
        curves["pressure_kpa"].sel(repetition=1, phase="inflate").values,
        table["rep_01_pressure_kpa"],
    )
    # the mean is the mean of the averaged repetitions (a second computation)
    averaged = curves["pressure_kpa"].sel(repetition=list(run.analysis.averaged))
    np.testing.assert_allclose(
        averaged.mean("repetition").values, curves["mean_pressure_kpa"].values, atol=1e-12
    )


def _digest(path):
    return hashlib.sha256(path.read_bytes()).hexdigest(), os.stat(path).st_mtime_ns


def test_reading_everything_writes_nothing(quick_run):
    import matplotlib

    matplotlib.use("Agg")
    before = _digest(quick_run)
    run = labrig.open_run(quick_run)
    run.raw(1, "length"), run.raw_table(1), run.curves, run.comparison, run.model_path
    run.plot()
    assert run.analysis_stored
    assert _digest(quick_run) == before


def test_plot_draws_the_figure_of_labrig_plot_on_given_axes(quick_run):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    run = labrig.open_run(quick_run)
    _, (ax_p, ax_l) = plt.subplots(2, 1)
    run.plot(ax=[ax_p, ax_l])
    assert ax_p.get_ylabel() == "pressure p (kPa)" and ax_l.get_ylabel() == "length l (mm)"
    mean = next(line for line in ax_p.lines if line.get_label() == "mean, inflation")
    np.testing.assert_array_equal(
        mean.get_ydata(), run.curves["mean_pressure_kpa"].sel(phase="inflate").values
    )
    _, ax_one = plt.subplots()
    assert run.plot(ax=ax_one) is ax_one and ax_one.get_ylabel() == "pressure p (kPa)"
    with pytest.raises(InputError, match="3 Axes given; this figure has 1 to 2 panels"):
        run.plot(ax=[ax_p, ax_l, ax_one])
    plt.close("all")


def test_a_killed_runs_file_is_read_as_it_was_and_flagged(killed_file):
    # read at once after the kill: its sidecar lock went with the process
    with pytest.warns(labrig.RunOpenWarning, match="killed.*labrig recover"):
        run = labrig.open_run(killed_file)
    assert run.writer_open and not run.live and run.status == "running"
    assert not run.complete
    assert list(run.repetitions["status"]) == ["running", "pending"]
    with h5py.File(killed_file, "r", swmr=True, locking=False) as h5:
        time_s = h5["entry/repetitions/rep_01/pressure/time"][:]
    assert len(time_s) > 0
    np.testing.assert_array_equal(run.raw(1)["time"].values, time_s)
    # the data so far, analysed in memory: the pressure rose 50 kPa/s, 5 kPa/mL
    table = run.curves_table("inflate").dropna(subset=["rep_01_pressure_kpa"])
    assert len(table) > 5
    np.testing.assert_allclose(table["rep_01_pressure_kpa"], 5 * table["volume_ml"], atol=0.1)
    assert writer_flag_set(killed_file)  # still flagged: reading repairs nothing


def test_a_run_file_that_is_not_flagged_gives_no_warning(tiny_file):
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        labrig.open_run(tiny_file)


def test_a_pipe_named_as_a_run_is_refused_not_waited_on(tmp_path):
    """The API opens through the commands' reader, which refuses what is no regular
    file before HDF5 opens it (HDF5 would wait forever on a pipe)."""
    pipe = tmp_path / "run.h5"
    os.mkfifo(pipe)
    with pytest.raises(InputError, match="not a regular file"):
        labrig.open_run(pipe)
