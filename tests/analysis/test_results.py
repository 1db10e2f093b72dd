"""The analysis group: stored, read back unchanged, replaced on re-analysis, and the
file's NeXus default plot."""

import dataclasses
import math

import h5py
import numpy as np
import pytest

from labrig.analysis import analyse_run
from labrig.analysis.curves import INFLATE
from labrig.analysis.report import summary_text
from labrig.analysis.results import read_analysis
from labrig.recording.run_reader import open_run


def assert_same(a, b, where="result"):
    """Equal field by field; arrays and floats NaN-aware; dict keys in order."""
    if dataclasses.is_dataclass(a):
        assert type(a) is type(b), where
        for f in dataclasses.fields(a):
            assert_same(getattr(a, f.name), getattr(b, f.name), f"{where}.{f.name}")
    elif isinstance(a, dict):
        assert list(a) == list(b), where
        for key in a:
            assert_same(a[key], b[key], f"{where}[{key}]")
    elif isinstance(a, list | tuple):
        assert len(a) == len(b), where
        for k, (x, y) in enumerate(zip(a, b, strict=True)):
            assert_same(x, y, f"{where}[{k}]")
    elif isinstance(a, np.ndarray):
        np.testing.assert_array_equal(a, b, err_msg=where)
    elif isinstance(a, float) and math.isnan(a):
        assert isinstance(b, float) and math.isnan(b), where
    else:
        assert a == b, f"{where}: {a!r} != {b!r}"


def test_round_trip_of_the_analysis_group(segment_run, copy_of):
    path = copy_of(segment_run)
    result = analyse_run(path)
    with open_run(path) as run:
        back = read_analysis(path, run)
    assert_same(result, back)
    assert result.averaged == (1, 2, 4, 5)
    assert [r.used_in_mean for r in back.repetitions] == [True, True, False, True, True]
    assert back.repetitions[2].status == "faulted"
    assert back.comparison is not None


def test_re_analysis_replaces_the_group_and_the_default_plot(segment_run, copy_of):
    path = copy_of(segment_run)
    analyse_run(path)
    analyse_run(path)
    with h5py.File(path, "r") as run:
        entry = run["entry"]
        assert [name for name in entry if name in ("analysis", "data")] == ["analysis", "data"]
        analysis = entry["analysis"]
        assert analysis.attrs["NX_class"] == "NXprocess"
        assert analysis["volume_ml"].attrs["units"] == "mL"
        assert analysis["mean/inflate_pressure_kpa"].attrs["units"] == "kPa"
        assert analysis["parameters/average_last"][()] == 4
        data = entry["data"]
        assert entry.attrs["default"] == "data"
        assert data.attrs["NX_class"] == "NXdata"
        assert data.attrs["signal"] == "pressure_kpa"
        assert list(data.attrs["axes"]) == ["volume_ml"]
        assert list(data.attrs["auxiliary_signals"]) == ["model_pressure_kpa"]
        # hard links into the analysis: the same datasets, stored once
        assert data["pressure_kpa"] == analysis["mean/inflate_pressure_kpa"]
        assert data["pressure_kpa_errors"] == analysis["mean/inflate_pressure_std_kpa"]
        assert data["model_pressure_kpa"] == analysis["model/inflate_pressure_kpa"]
        assert data["volume_ml"].shape == data["pressure_kpa"].shape


def test_the_mean_is_the_mean_of_the_stored_repetition_curves(segment_run, copy_of):
    """An independent recomputation from the stored per-repetition curves."""
    path = copy_of(segment_run)
    analyse_run(path)
    with h5py.File(path, "r") as run:
        reps = run["entry/analysis/repetitions"]
        curves = np.vstack([reps[f"rep_0{i}/inflate_pressure_kpa"][()] for i in (1, 2, 4, 5)])
        stored = run["entry/analysis/mean/inflate_pressure_kpa"][()]
        spread = run["entry/analysis/mean/inflate_pressure_std_kpa"][()]
    inside = np.all(np.isfinite(curves), axis=0)
    assert inside.sum() > 350  # 0..20.8 mL on a 0.05 mL grid
    np.testing.assert_allclose(stored[inside], curves[:, inside].mean(axis=0), rtol=1e-12)
    np.testing.assert_allclose(spread[inside], curves[:, inside].std(axis=0, ddof=1), rtol=1e-9)


def test_summary_text_tabulates_repetitions_and_the_model(segment_run):
    from labrig.analysis import analyse

    result = analyse(segment_run.path)
    text = summary_text(result)
    assert "repetition 3 faulted: simulated fault" in text
    assert "against the model (SI-B46-T20)" in text
    rmse = result.comparison.rmse_p_kpa[INFLATE]
    assert f"{rmse:.3f}" in text


def test_many_transitions_wrap_and_leave_the_other_columns_whole(segment_run):
    # eight transitions a repetition (a bulging library's steep stretches) once squeezed
    # every other column of the run's 110-column summary to one letter and an ellipsis
    from labrig.analysis import analyse
    from labrig.analysis.transitions import MeasuredTransition

    result = analyse(segment_run.path)
    many = tuple(
        MeasuredTransition(
            1, 1, 10.0 + k, 5.0 + 3 * k, 4.9 + 3 * k, 5.1 + 3 * k, -9.0, 0.4, True, k % 2 == 0
        )
        for k in range(8)
    )
    first = dataclasses.replace(result.repetitions[0], transitions=many)
    result = dataclasses.replace(result, repetitions=(first, *result.repetitions[1:]))
    text = summary_text(result, width=110)
    rows = text[text.index("repetitions (") :].splitlines()
    assert "status" in rows[1] and "samples" in rows[1] and "transitions" in rows[1]
    assert "…" not in "\n".join(rows[:8])
    listed = " ".join(rows[3:8])
    for t in many:
        assert f"+{t.v_ml:.2f}({t.kind})" in listed


def test_analysis_of_a_file_without_entry_is_refused(tmp_path):
    from labrig.errors import InputError

    path = tmp_path / "foreign.h5"
    with h5py.File(path, "w") as f:
        f["x"] = 1
    with pytest.raises(InputError, match="missing /entry"):
        analyse_run(path)
