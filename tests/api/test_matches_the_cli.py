"""The API's names and fields are the command line's JSON, value for value."""

import json
import math
import subprocess
import sys

import numpy as np
import pytest
from support.api_runs import cli

import labrig
from labrig.vocabulary import ALIASES


def _nulls(records):
    """NaN (pandas' missing) as None (JSON's null), for comparing records."""
    return [
        {k: None if isinstance(v, float) and math.isnan(v) else v for k, v in row.items()}
        for row in records
    ]


def test_comparison_is_compare_json(quick_run, capsys):
    code, out, err = cli(["compare", quick_run, "--json"], capsys)
    assert code == 0, err
    printed = json.loads(out)
    run = labrig.open_run(quick_run)
    assert run.comparison_document == printed
    table = run.comparison
    assert list(table.columns) == list(printed["transitions"][0])
    assert _nulls(table.to_dict("records")) == printed["transitions"]
    # each of the JSON's names is followed by its vocabulary name, with its value
    for row in printed["transitions"] + printed["paper_transitions"] + printed["unpredicted"]:
        names = list(row)
        for old, new in ALIASES["comparison"].items():
            if old in row:
                assert names[names.index(old) + 1] == new and row[new] == row[old]
    assert run.rmse.to_dict() == printed["rmse"]
    paper = run.paper_comparison
    assert _nulls(paper.to_dict("records")) == printed["paper_transitions"]
    assert "snap" in set(table["type"])


def test_path_is_model_path_json(capsys):
    segments = ("B48-T30", "B50-T20")
    code, out, err = cli(["model", "path", *segments, "--deflate", "--json"], capsys)
    assert code == 0, err
    printed = json.loads(out)
    path = labrig.actuator(*segments).path(deflate=True)
    assert out == json.dumps(path.document) + "\n"  # byte for byte: one builder
    assert path.document == printed
    assert path.transitions.to_dict("records") == printed["transitions"]
    assert path.paper_transitions.to_dict("records") == printed["paper_transitions"]
    table = path.path
    for name in ("v_ml", "p_kpa", "l_mm"):
        assert table[name].tolist() == printed["path"][name]
    for i, values in enumerate(printed["path"]["v_i_ml"], 1):
        assert table[f"v{i}_ml"].tolist() == values
    # an invariant, not the code's own output: the segments' volumes add up to the total
    np.testing.assert_allclose(table["v1_ml"] + table["v2_ml"], table["v_ml"], atol=2e-6)


def test_three_segments_path_is_model_path_json_byte_for_byte(capsys):
    segments = ("B46-T20", "B46-T22", "B46-T24")
    code, out, err = cli(["model", "path", *segments, "--v-end-ml", "30", "--json"], capsys)
    assert code == 0, err
    path = labrig.actuator(*segments).path(v_end_ml=30.0)
    assert out == json.dumps(path.document) + "\n"
    assert len(json.loads(out)["path"]["v_i_ml"]) == 3


def test_segment_is_model_curve_json(capsys):
    code, out, err = cli(["model", "curve", "B46-T20", "--json"], capsys)
    assert code == 0, err
    printed = json.loads(out)
    segment = labrig.segment("B46-T20")
    assert out == json.dumps(segment.document) + "\n"  # byte for byte: one builder
    assert segment.name == printed["name"] and segment.V0_ml == printed["V0_ml"]
    assert segment.peak == printed["peak"] and segment.valley == printed["valley"]
    for name in ("v_ml", "p_kpa", "l_mm"):
        assert segment.curve[name].tolist() == printed[name]


@pytest.fixture(scope="module")
def campaign(quick_run, tmp_path_factory):
    """The quick run, a run without a comparison, and a file that is no run."""
    import shutil

    from support.simulated_runs import tiny_run

    folder = tmp_path_factory.mktemp("campaign")
    shutil.copyfile(quick_run, folder / "a_quick.h5")
    tiny_run(folder / "b_tiny.h5")
    (folder / "c_broken.h5").write_bytes(b"not a run file")
    return folder


def test_open_runs_is_runs_json_and_csv(campaign, tmp_path, capsys):
    import pandas as pd  # imported where it runs, not in every worker's collection

    code, out, err = cli(["runs", campaign, "--json", "--csv", tmp_path / "runs.csv"], capsys)
    assert code == 0, err
    printed = json.loads(out)["runs"]
    table = labrig.open_runs(campaign)
    assert list(table.columns) == list(printed[0])
    # the date: ISO 8601 text in the JSON, a datetime in the table
    dates = pd.to_datetime([row["date"] for row in printed], utc=True)
    assert list(table["date"].iloc[:2]) == list(dates[:2]) and pd.isna(table["date"].iloc[2])
    printed_dates = [row.pop("date") for row in printed]
    assert _nulls(table.drop(columns="date").to_dict("records")) == printed
    for row, date in zip(printed, printed_dates, strict=True):
        row["date"] = date
    from_csv = pd.read_csv(tmp_path / "runs.csv")
    assert list(from_csv.columns) == list(table.columns)
    np.testing.assert_allclose(from_csv["snap1_v_ml"], table["snap1_v_ml"].astype(float))

    quick, tiny, broken = printed
    assert quick["status"] == "complete" and quick["seed"] == 3
    assert quick["specimen"] == "B48-T30 + B50-T20"
    assert "no comparison with the model" in tiny["note"] and tiny["status"] == "complete"
    assert tiny["snap1_v_ml"] is None
    assert "not an HDF5 file" in broken["error"] and broken["status"] is None


def test_a_campaigns_snaps_are_compares_paper_transitions(campaign, capsys):
    """The snap columns are the snaps of ``compare --json``'s ``paper_transitions`` (the
    events at one supplied volume counted as one, as the paper counts them),
    in order and no more; the error is measured minus model."""
    run_file = campaign / "a_quick.h5"
    code, out, err = cli(["compare", run_file, "--json"], capsys)
    assert code == 0, err
    snaps = [t for t in json.loads(out)["paper_transitions"] if t["type"] == "snap"]
    assert len(snaps) >= 2
    code, out, err = cli(["runs", run_file, "--json"], capsys)
    assert code == 0, err
    (row,) = json.loads(out)["runs"]
    assert f"snap{len(snaps)}_phase" in row and f"snap{len(snaps) + 1}_phase" not in row
    for k, snap in enumerate(snaps, 1):
        assert row[f"snap{k}_phase"] == snap["phase"]
        for short, unit in (("v", "ml"), ("dp", "kpa"), ("dl", "mm")):
            seen, model = snap[f"{short}_meas_{unit}"], snap[f"{short}_{unit}"]
            assert row[f"snap{k}_{short}_{unit}"] == seen
            assert row[f"snap{k}_{short}_model_{unit}"] == model
            error = row[f"snap{k}_{short}_error_{unit}"]
            assert error is None if seen is None else error == pytest.approx(seen - model)


def test_runs_refuses_what_names_no_run(tmp_path, capsys):
    code, _, err = cli(["runs", tmp_path / "none*.h5"], capsys)
    assert code == 2 and "no run files (*.h5) found" in err
    code, _, err = cli(["runs", tmp_path, "--csv", tmp_path / "missing" / "x.csv"], capsys)
    assert code == 2 and "does not exist" in err


def test_labrig_starts_without_pandas_or_xarray():
    """The API's names are imported on first use: `labrig --help` stays fast."""
    probe = (
        "import sys; from labrig.cli import cli; import labrig\n"
        "try: cli.main(['--help'], standalone_mode=False)\n"
        "except SystemExit: pass\n"
        "print(sorted(m for m in ('pandas', 'xarray') if m in sys.modules))"
    )
    out = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True).stdout
    assert out.splitlines()[-1] == "[]"


def test_runs_prints_each_run_with_its_snaps_measured_and_predicted(campaign, capsys, monkeypatch):
    monkeypatch.setenv("COLUMNS", "200")  # a wide terminal: one line a snap
    code, out, err = cli(["runs", campaign / "a_*.h5", campaign / "b_tiny.h5"], capsys)
    assert code == 0, err
    row = labrig.open_runs([campaign / "a_quick.h5"]).iloc[0]
    assert "a_quick.h5" in out and "b_tiny.h5" in out and "c_broken" not in out
    assert f"v {row['snap1_v_ml']:.2f} ({row['snap1_v_model_ml']:.2f})" in out
    assert len(labrig.open_runs(str(campaign / "[ab]_*.h5"))) == 2


def test_the_long_campaign_is_one_row_per_transition(campaign, capsys):
    """One row per transition of compare --json (paper_transitions, then unpredicted),
    in the vocabulary's names, with the protocol's parameters; a run without a
    comparison and a broken file are one row each, saying why."""
    import pandas as pd

    code, out, err = cli(["compare", campaign / "a_quick.h5", "--json"], capsys)
    assert code == 0, err
    printed = json.loads(out)
    table = labrig.open_runs(campaign, long=True)
    quick = table[table["file"].str.endswith("a_quick.h5")]
    expected = printed["paper_transitions"] + printed["unpredicted"]
    assert len(quick) == len(expected)
    assert list(quick["direction"]) == [t["phase"] for t in expected]
    assert list(quick["type"]) == [t.get("type", "unpredicted") for t in expected]
    seen = [None if v != v else v for v in quick["v_measured_ml"]]  # NaN is null
    assert seen == [t["v_meas_ml"] for t in expected]
    snaps = quick[quick["type"] == "snap"]
    paper_snaps = [t for t in printed["paper_transitions"] if t["type"] == "snap"]
    assert list(snaps["dE_model"]) == [t["dE_model"] for t in paper_snaps]
    # the quick demo: 60 mL/min both ways to 30 mL, twice, 10 mm of fittings
    assert set(quick["rate_ml_min"]) == set(quick["withdraw_rate_ml_min"]) == {60.0}
    assert set(quick["max_volume_ml"]) == {30.0} and set(quick["repetitions"]) == {2}
    assert set(quick["fittings_length_mm"]) == {10.0}
    assert isinstance(quick["date"].iloc[0], pd.Timestamp)
    tiny = table[table["file"].str.endswith("b_tiny.h5")]
    broken = table[table["file"].str.endswith("c_broken.h5")]
    assert len(tiny) == 1 and "no comparison with the model" in tiny["note"].iloc[0]
    assert len(broken) == 1 and "not an HDF5 file" in broken["error"].iloc[0]


def test_note_and_error_are_columns_whichever_runs(quick_run):
    """A campaign of good runs has them too (null), so code reading them never breaks."""
    for long in (False, True):
        table = labrig.open_runs(quick_run, long=long)
        assert list(table.columns[-2:]) == ["note", "error"]
        assert table["note"].isna().all() and table["error"].isna().all()
