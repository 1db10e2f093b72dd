"""``labrig model path`` through the real entry point: the JSON contract, the table,
deflation, the plot, CSV segments, and bad input as one line with exit code 2."""

import itertools
import json

import numpy as np
import pytest

from labrig.cli import main
from labrig.model.segments.catalog import analytical_segment
from labrig.model.segments.measured import write_csv


def run(argv, capsys):
    with pytest.raises(SystemExit) as exited:
        main(argv)
    out, err = capsys.readouterr()
    return exited.value.code, out, err


def test_json_follows_the_design_contract(capsys):
    code, out, err = run(["model", "path", "SI-B48-T30", "SI-B50-T20", "--json"], capsys)
    assert code == 0 and err == ""
    doc = json.loads(out)
    assert list(doc) == ["segments", "path", "transitions", "paper_transitions"]
    assert doc["segments"] == ["SI-B48-T30", "SI-B50-T20"]
    path = doc["path"]
    # the contract's arrays in order, each with its vocabulary name right after it
    assert list(path) == ["v_ml", "volume_ml", "p_kpa", "pressure_kpa", "l_mm",
                          "segments_length_mm", "v_i_ml"]  # fmt: skip
    assert path["volume_ml"] == path["v_ml"] and path["segments_length_mm"] == path["l_mm"]
    n_points = len(path["v_ml"])
    assert len(path["v_i_ml"]) == 2 and all(len(v) == n_points for v in path["v_i_ml"])
    v_i = np.array(path["v_i_ml"])
    np.testing.assert_allclose(v_i.sum(axis=0), path["v_ml"], atol=3e-6)
    for name, v in zip(doc["segments"], v_i, strict=True):
        np.testing.assert_allclose(
            analytical_segment(name).pressure_kpa(v), path["p_kpa"], atol=1e-4
        )
    assert np.all(np.diff(path["v_ml"]) >= 0)  # inflation only
    keys = ["v_ml", "alpha", "beta", "stable", "dE", "dv", "dl", "dp", "direction"]
    assert all(list(t) == keys for t in doc["transitions"])
    kinds = [(t["alpha"], t["beta"], t["stable"]) for t in doc["transitions"]]
    assert kinds == [(0, 1, True), (1, 2, True), (2, 1, False), (1, 2, True)]
    snap = doc["transitions"][2]
    assert snap["direction"] == "inflate" and snap["dE"] < 0 and snap["dv"] > 0.3
    # the snap follows the crossing before it by 3.1 mL: each is a transition of its own
    assert [t.pop("events") for t in doc["paper_transitions"]] == [[0], [1], [2], [3]]
    assert doc["paper_transitions"] == doc["transitions"]
    # a snap is two points of the path at the same volume
    jumps = np.flatnonzero(np.diff(path["v_ml"]) == 0)
    assert len(jumps) == 1 and path["v_ml"][jumps[0]] == pytest.approx(snap["v_ml"], abs=1e-6)


def test_deflate_adds_the_way_back_with_its_own_transitions(capsys):
    code, out, _ = run(["model", "path", "SI-B48-T30", "SI-B50-T20", "--deflate", "--json"], capsys)
    assert code == 0
    doc = json.loads(out)
    v = np.array(doc["path"]["v_ml"])
    top = int(np.argmax(v))
    assert np.all(np.diff(v[: top + 1]) >= 0) and np.all(np.diff(v[top:]) <= 0)
    assert v[0] == 0 and v[-1] == pytest.approx(0, abs=1e-6)
    directions = [t["direction"] for t in doc["transitions"]]
    assert directions == ["inflate"] * 4 + ["deflate"] * 3
    up = [t["v_ml"] for t in doc["transitions"] if not t["stable"] and t["direction"] == "inflate"]
    down = [
        t["v_ml"] for t in doc["transitions"] if not t["stable"] and t["direction"] == "deflate"
    ]
    assert down[0] < up[0] - 5  # hysteresis


def test_the_table_lists_every_transition(capsys):
    code, out, _ = run(["model", "path", "SI-B44-T30", "SI-B48-T26", "--deflate"], capsys)
    assert code == 0
    rows = [
        line.split() for line in out.splitlines() if line.strip().startswith(("inflate", "deflate"))
    ]
    assert len(rows) == 8
    assert rows[2][:6] == ["inflate", "18.894", "(2,", "1)", "unstable", "snap"]
    assert "8 transitions" in out


def test_three_segments_and_a_plot(tmp_path, capsys):
    png = tmp_path / "path.png"
    code, out, _ = run(
        ["model", "path", "SI-B40-T28", "SI-B44-T30", "SI-B50-T24", "--plot", str(png)], capsys
    )
    assert code == 0 and f"plot: {png}" in out
    import matplotlib.image

    image = matplotlib.image.imread(png)
    assert image.shape[0] > 400 and image.shape[1] > 900
    assert image[..., :3].std() > 0.05  # something is drawn


def test_pairs_plot_the_v1_v2_plane(tmp_path, capsys):
    png = tmp_path / "pair.png"
    code, _, _ = run(
        ["model", "path", "SI-B46-T20", "SI-B46-T22", "--deflate", "--plot", str(png)], capsys
    )
    assert code == 0
    import matplotlib.image

    assert matplotlib.image.imread(png).shape[1] > 1500  # three panels


def test_measured_csv_segments(tmp_path, capsys):
    paths = []
    for name in ("SI-B44-T30", "SI-B48-T26"):
        paths.append(str(tmp_path / f"{name}.csv"))
        write_csv(analytical_segment(name), paths[-1])
    code, out, _ = run(["model", "path", *paths, "--json"], capsys)
    assert code == 0
    from_csv = json.loads(out)["transitions"]
    _, out, _ = run(["model", "path", "SI-B44-T30", "SI-B48-T26", "--json"], capsys)
    from_library = json.loads(out)["transitions"]
    assert [(t["alpha"], t["beta"], t["stable"]) for t in from_csv] == [
        (t["alpha"], t["beta"], t["stable"]) for t in from_library
    ]
    for a, b in zip(from_csv, from_library, strict=True):
        assert a["v_ml"] == pytest.approx(b["v_ml"], abs=0.05)


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["SI-B46-T20"], "at least two segments, got 1"),
        ([], "at least two segments, got 0"),
        (["SI-B46-T20", "SI-B99-T20"], "unknown segment 'SI-B99-T20'"),
        (["SI-B46-T20", "SI-B46-T22", "--v-end-ml", "-3"], "--v-end-ml=-3.0: the end volume"),
        (["SI-B46-T20", "SI-B46-T22", "--v-end-ml", "inf"], "--v-end-ml=inf: the end volume"),
        (["SI-B46-T20", "SI-B46-T22", "--v-end-ml", "nan"], "--v-end-ml=nan: the end volume"),
        (["SI-B46-T20", "SI-B46-T22", "--plot", "/no/such/dir/x.png"], "--plot /no/such/dir/x.png"),
    ],
)
def test_bad_input_is_one_line_and_exit_2(argv, message, capsys):
    code, out, err = run(["model", "path", *argv], capsys)
    assert code == 2 and out == ""
    assert len(err.strip().splitlines()) == 1 and message in err


def test_the_model_group_lists_path(capsys):
    code, out, _ = run(["model", "--help"], capsys)
    assert code == 0 and "path" in out and "curve" in out


def test_an_unresolvable_state_is_one_line_naming_segments_and_volume(capsys, monkeypatch):
    """Whatever fails inside the solver (here every bracketed root, as a table outside
    the model's assumptions would), the user sees one line and exit code 2; --debug
    shows the traceback."""
    import labrig.model.actuator.path as path_module

    def no_root(*args):
        raise ValueError("no sign change between the ends of the bracket")

    monkeypatch.setattr(path_module, "bracketed_root", no_root)
    code, _, err = run(["model", "path", "SI-B42-T24", "SI-B50-T22"], capsys)
    assert code == 2
    assert err.startswith(
        "error: SI-B42-T24 + SI-B50-T22: the model cannot resolve the state near v = "
    )
    assert "no sign change" in err and "Traceback" not in err and len(err.splitlines()) == 1
    with pytest.raises(path_module.PathError):
        main(["--debug", "model", "path", "SI-B42-T24", "SI-B50-T22"])


def test_any_other_error_is_one_line_unless_debug(capsys, monkeypatch):
    import labrig.model.path_document as path_document_module

    def broken(path, window_ml=1e-4):
        raise ZeroDivisionError("a bug")

    # the transitions of the solved path, as the command calls them
    monkeypatch.setattr(path_document_module, "transitions", broken)
    code, _, err = run(["model", "path", "SI-B42-T24", "SI-B50-T22"], capsys)
    assert code == 1
    assert err.strip() == (
        "error: internal error (ZeroDivisionError: a bug); labrig --debug ... shows the traceback"
    )
    with pytest.raises(ZeroDivisionError):
        main(["--debug", "model", "path", "SI-B42-T24", "SI-B50-T22"])


def test_the_papers_counting_groups_only_events_at_one_supplied_volume(capsys):
    """B46-T20 + B46-T22 (Movie S3): each paper transition is made of events at one
    supplied volume, two transitions are never at one, and its relative changes are
    its events' compounded."""
    code, out, _ = run(["model", "path", "B46-T20", "B46-T22", "--json"], capsys)
    assert code == 0
    doc = json.loads(out)
    events, counted = doc["transitions"], doc["paper_transitions"]
    assert sorted(i for t in counted for i in t["events"]) == list(range(len(events)))
    for t in counted:
        members = [events[i] for i in t["events"]]
        assert all(abs(e["v_ml"] - t["v_ml"]) <= 1e-6 for e in members)
        for name in ("dE", "dl", "dp"):
            assert t[name] == pytest.approx(np.prod([1 + e[name] for e in members]) - 1, abs=2e-6)
    volumes = [t["v_ml"] for t in counted]
    assert all(b - a > 1e-6 for a, b in itertools.pairwise(volumes))
