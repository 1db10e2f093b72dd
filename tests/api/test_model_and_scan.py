"""``labrig.segment``, ``labrig.actuator`` and ``labrig.open_scan``: tables and plots."""

import json

import h5py
import numpy as np
import pytest
from support.api_runs import cli

import labrig
from labrig.errors import InputError


@pytest.fixture(autouse=True)
def plt():
    """pyplot on Agg, every figure closed after each test; imported when the tests run,
    not as every worker collects them (matplotlib is a second of CPU a process)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as pyplot

    yield pyplot
    pyplot.close("all")


def test_a_path_plot_on_one_axes_is_the_pressure_panel(plt):
    path = labrig.actuator("B48-T30", "B50-T20").path()
    _, ax = plt.subplots()
    assert path.plot(ax=ax) is ax
    assert ax.get_ylabel() == "pressure p (kPa)"
    inflation = next(line for line in ax.lines if line.get_label() == "inflation")
    table = path.path
    # the drawn curve is the path's table (inflation only: every row), to its 6 decimals
    np.testing.assert_allclose(inflation.get_xdata(), table["v_ml"], atol=1e-6)
    np.testing.assert_allclose(inflation.get_ydata(), table["p_kpa"], atol=1e-6)
    snaps = path.transitions[~path.transitions["stable"]]
    drawn = [line for line in ax.lines if line.get_marker() == "v" and len(line.get_xdata())]
    assert len(drawn) == len(snaps) > 0
    # its summary counts as the paper does (the events at one supplied volume are one)
    counted, events = len(path.paper_transitions), len(path.transitions)
    assert 0 < counted <= events
    assert repr(path) == (
        f"<labrig.ActuatorPath B48-T30 + B50-T20: {counted} transitions as the paper "
        f"counts them ({events} events)>"
    )


def test_a_path_plot_without_axes_has_the_commands_three_panels():
    axes = labrig.actuator("B48-T30", "B50-T20").path().plot()
    assert len(axes) == 3
    assert axes[2].get_xlabel().startswith("v1 (B48-T30)")


def test_a_segment_plot_and_its_errors():
    segment = labrig.segment("B46-T20")
    ax_p, ax_l = segment.plot()
    assert ax_l.get_ylabel() == "length l (mm)"
    peak = next(line for line in ax_p.lines if line.get_label() == "peak")
    assert peak.get_xdata()[0] == segment.peak["v_ml"]
    with pytest.raises(InputError, match="at least two segments"):
        labrig.actuator("B46-T20")
    with pytest.raises(InputError):
        labrig.segment("no-such-segment")


def test_a_measured_csv_segment(tmp_path, capsys):
    v = np.linspace(0, 10, 200)
    csv = tmp_path / "measured.csv"
    rows = "\n".join(f"{a},{3 * a},{40 + 0.5 * a}" for a in v)
    csv.write_text("volume_ml,pressure_kpa,length_mm\n" + rows + "\n")
    segment = labrig.segment(csv)
    np.testing.assert_allclose(segment.curve["p_kpa"], 3 * segment.curve["v_ml"], atol=1e-9)
    # what was done to the table is the command's too, byte for byte
    code, out, err = cli(["model", "curve", csv, "--json"], capsys)
    assert code == 0, err
    assert out == json.dumps(segment.document) + "\n"
    assert segment.document["measured"]["rows"] == 200


def test_a_scan_is_its_files_rows_with_names(gent_scan):
    scan = labrig.open_scan(gent_scan)
    assert scan.complete and scan.n == 2 and scan.actuators_done == 3
    table = scan.transitions
    with h5py.File(gent_scan, "r") as h5:
        rows = h5["transitions"]
        names = [n.decode() for n in h5["segments/name"][:]]
        assert len(table) == len(scan) == len(rows["v_ml"])
        for field in ("actuator", "v_ml", "alpha", "beta", "stable", "dE", "dp"):
            np.testing.assert_array_equal(table[field].to_numpy(), rows[field][:])
        # the file's +1/-1 is the table's direction_sign, named in direction
        np.testing.assert_array_equal(table["direction_sign"], rows["direction"][:])
        named = np.where(rows["direction"][:] > 0, "inflate", "deflate")
        np.testing.assert_array_equal(table["direction"].to_numpy(), named)
        index = rows["segments"][:]
    assert list(table["segment1"]) == [names[i] for i in index[:, 0]]
    assert list(table["segment2"]) == [names[i] for i in index[:, 1]]
    part = scan.table(1, 3)
    assert part.reset_index(drop=True).equals(table.iloc[1:3].reset_index(drop=True))
    # counted as the paper counts them: no more rows, the same changes over all (the
    # counting's invariant: flows add, relative changes compound)
    paper = scan.paper_transitions
    assert 0 < len(paper) <= len(table)
    assert paper["dv"].sum() == pytest.approx(table["dv"].sum(), abs=1e-9)
    for name in ("dl", "dp"):
        assert np.log1p(paper[name]).sum() == pytest.approx(np.log1p(table[name]).sum(), abs=1e-9)
    first = paper["first"].to_numpy()
    assert list(paper["segment1"]) == list(table["segment1"].to_numpy()[first])
    axes = scan.plot()
    assert len(axes) == 3 and axes[0].get_xlabel() == "energy change ΔÊ"
    with pytest.raises(InputError, match="no such file"):
        labrig.open_scan(gent_scan.parent / "missing.h5")


def test_an_actuator_from_a_list_and_a_clear_end_volume():
    assert labrig.actuator(["B48-T30", "B50-T20"]).names == ["B48-T30", "B50-T20"]
    assert labrig.actuator(("B48-T30", "B50-T20")).names == ["B48-T30", "B50-T20"]
    with pytest.raises(InputError, match="at least two segments, got 1"):
        labrig.actuator(["B48-T30"])
    for wrong in (-1, float("nan"), True, "10"):
        with pytest.raises(InputError, match=r"fittings_length_mm=.*: the fittings' length, mm"):
            labrig.actuator("B48-T30", "B50-T20", fittings_length_mm=wrong)
    pair = labrig.actuator("B48-T30", "B50-T20")
    for wrong in (-1, 0, float("nan"), float("inf"), "3", True):
        with pytest.raises(InputError, match=r"v_end_ml=.*: the end volume of inflation, mL, > 0"):
            pair.path(v_end_ml=wrong)


def test_a_scan_row_becomes_its_actuator_and_a_subset_is_drawn(gent_scan):
    scan = labrig.open_scan(gent_scan)
    paper, events = scan.paper_transitions, scan.transitions
    row = paper.iloc[len(paper) // 2]
    built = scan.actuator(row)
    assert built.names == [row["segment1"], row["segment2"]]
    assert scan.actuator(int(row["actuator"])).names == built.names
    # solved again, whole: the same events the scan stored for that actuator
    stored = events[events["actuator"] == row["actuator"]]
    solved = built.path().transitions
    np.testing.assert_allclose(solved["v_ml"], stored["v_ml"], atol=1e-6)
    np.testing.assert_allclose(solved["dE"], stored["dE"], rtol=1e-5)
    for wrong, message in ((3, "ranks are 0 to 2"), (-1, "ranks are 0 to 2"), ("x", "a row")):
        with pytest.raises(InputError, match=message):
            scan.actuator(wrong)
    subset = paper[paper["direction"] == "inflate"].head(2)
    axes = scan.plot(transitions=subset)
    drawn = sum(len(c.get_offsets()) for c in axes[0].collections)
    assert drawn == len(subset) == 2
    with pytest.raises(InputError, match="no column dE"):
        scan.plot(transitions=subset.drop(columns="dE"))
