"""``labrig model curve`` through the real entry point: summary, JSON, plot, bad input."""

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


def test_summary_names_peak_valley_and_contact(capsys):
    code, out, _ = run(["model", "curve", "SI-B46-T20"], capsys)
    assert code == 0
    assert "peak     39.55 kPa at 5.358 mL" in out
    assert "valley   32.99 kPa at 19.780 mL" in out
    assert "contact  19.780 mL" in out
    assert "V0       2.534 mL" in out


def test_json_is_the_table_with_its_extrema(capsys):
    code, out, _ = run(["model", "curve", "si-b46-t22", "--json"], capsys)
    assert code == 0
    doc = json.loads(out)
    # the contract's fields in order, each array with its vocabulary name right after it
    assert list(doc) == ["name", "V0_ml", "peak", "valley", "v_ml", "volume_ml", "p_kpa",
                         "pressure_kpa", "l_mm", "segments_length_mm"]  # fmt: skip
    assert doc["name"] == "SI-B46-T22"
    curve = analytical_segment("SI-B46-T22")
    np.testing.assert_array_equal(doc["p_kpa"], curve.p_kpa)
    k = doc["v_ml"].index(doc["peak"]["v_ml"])  # the peak is a sample of the table
    assert doc["p_kpa"][k] == doc["peak"]["p_kpa"] == max(doc["p_kpa"][: k + 10])
    assert doc["valley"]["v_ml"] > doc["peak"]["v_ml"]


def test_json_has_null_extrema_when_contact_comes_first(capsys):
    code, out, _ = run(["model", "curve", "SI-B40-T30", "--json"], capsys)
    assert code == 0
    doc = json.loads(out)
    assert doc["peak"] is None and doc["valley"] is None


def test_plot_and_csv_input(tmp_path, capsys):
    write_csv(analytical_segment("SI-B50-T20"), tmp_path / "b50.csv")
    png = tmp_path / "b50.png"
    code, out, _ = run(["model", "curve", str(tmp_path / "b50.csv"), "--plot", str(png)], capsys)
    assert code == 0
    assert out.startswith("b50: measured curve")
    assert "contact" not in out  # only analytical segments know their contact
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and png.stat().st_size > 20_000


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["model", "curve", "SI-B47-T20"], "unknown segment 'SI-B47-T20'"),
        (["model", "curve", "missing.csv"], "missing.csv: no such file"),
        (["model", "curve", "SI-B46-T20", "--plot", "/no/such/dir/x.png"], "does not exist"),
    ],
)
def test_bad_input_is_one_line_and_exit_2(argv, message, capsys):
    code, out, err = run(argv, capsys)
    assert code == 2 and out == ""
    assert err.count("\n") == 1 and message in err and "Traceback" not in err


def test_bad_csv_is_one_line_and_exit_2(tmp_path, capsys):
    bad = tmp_path / "bad.csv"
    bad.write_text("volume_ml,pressure_kpa,length_mm\n0,0,20\n0.1,x,20\n")
    code, _, err = run(["model", "curve", str(bad)], capsys)
    assert code == 2
    assert err.strip() == (
        f"error: {bad}: line 3, column pressure_kpa: not a number (a decimal number such as "
        "12.5 or 1.25e1)"
    )


def test_a_measured_table_says_what_was_done_and_plots_the_raw_rows(tmp_path, capsys):
    clean = analytical_segment("SI-B42-T24")
    v = np.linspace(0.0, clean.v_max_ml, 8000).tolist()
    rows = ["volume_ml,pressure_kpa,length_mm"]
    p = np.round(clean.pressure_kpa(v), 2).tolist()
    rows += [
        f"{a!r},{b!r},{c!r}" for a, b, c in zip(v, p, clean.length_mm(v).tolist(), strict=True)
    ]
    table = tmp_path / "rounded.csv"
    table.write_text("\n".join(rows) + "\n")
    png = tmp_path / "c.png"
    code, out, _ = run(["model", "curve", str(table), "--plot", str(png)], capsys)
    assert code == 0
    assert "import   used as tabulated" in out
    assert "rows     8000 rows, spacing 0.002049 mL, step 0.01 kPa, noise" in out
    assert "peaks    1 peak kept (dip 1.66 kPa; dips above 0.03 kPa count)" in out
    assert png.stat().st_size > 10_000
    code, out, _ = run(["model", "curve", str(table), "--json"], capsys)
    measured = json.loads(out)["measured"]
    assert measured["route"] == "tabulated" and measured["rows"] == 8000
    assert measured["step_kpa"] == pytest.approx(0.01) and measured["peaks_kept"] == 1
