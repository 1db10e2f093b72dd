"""``labrig library add``: a single-segment run becomes a measured segment that works
wherever a SEG does."""

import hashlib
import json
from pathlib import Path

import numpy as np
import pytest

from labrig.cli import main
from labrig.model.segments.catalog import analytical_segment, load_segment


def run(argv, capsys):
    with pytest.raises(SystemExit) as exited:
        main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return exited.value.code, out, err


def test_add_makes_a_segment_with_its_provenance(segment_run, tmp_path, capsys):
    library = tmp_path / "lib"
    code, out, err = run(
        ["library", "add", segment_run.path, "--name", "S46-20a", "--library", library], capsys
    )
    assert code == 0, err
    assert out.startswith(f"{library}/S46-20a.csv: measured segment 'S46-20a'")
    provenance = json.loads((library / "S46-20a.json").read_text())
    run_file = provenance["run"]
    assert run_file["sha256"] == hashlib.sha256(segment_run.path.read_bytes()).hexdigest()
    assert run_file["specimen"] == ["SI-B46-T20"]
    assert provenance["repetitions_averaged"] == [1, 2, 4, 5]

    # the measured segment reproduces the plant's segment, which the analysis never saw
    measured = load_segment("S46-20a", library_dir=library)
    truth = analytical_segment("SI-B46-T20")
    assert measured.peak.p_kpa == pytest.approx(truth.peak.p_kpa, abs=0.25)
    assert measured.peak.v_ml == pytest.approx(truth.peak.v_ml, abs=0.5)
    assert measured.valley.v_ml == pytest.approx(truth.valley.v_ml, abs=0.5)
    v = np.linspace(0.5, 20.0, 40)
    np.testing.assert_allclose(measured.pressure_kpa(v), truth.pressure_kpa(v), atol=0.6)
    # the fittings are taken off: the segment's own length
    np.testing.assert_allclose(measured.length_mm(v), truth.length_mm(v), atol=0.05)


def test_a_library_segment_works_where_a_seg_does(segment_run, tmp_path, capsys, monkeypatch):
    library = tmp_path / "lib"
    run(["library", "add", segment_run.path, "--name", "mine", "--library", library], capsys)
    monkeypatch.setenv("LABRIG_LIBRARY", str(library))
    code, out, _ = run(["model", "curve", "mine"], capsys)
    assert code == 0
    assert out.startswith("mine: measured curve")
    # and as the model of a comparison: the run against its own measured segment
    code, out, _ = run(["compare", segment_run.path, "--segments", "mine"], capsys)
    assert code == 0
    line = next(s for s in out.splitlines() if s.strip().startswith("inflate"))
    rmse_p, rmse_l = (float(x) for x in line.split()[1:3])
    # 0.43 kPa as against the analytical curve (the inlet's R Q and the sensor offset,
    # see tests/analysis/test_compare.py) plus ~0.2 kPa from the shape fit's zero,
    # extrapolated to v = 0 from its first bins on the steep initial rise
    assert rmse_p < 0.75 and rmse_l < 0.05


def test_add_refuses_what_is_not_a_single_segment_run(snap_run, tmp_path, capsys):
    code, _, err = run(["library", "add", snap_run.path, "--name", "x"], capsys)
    assert code == 2
    assert "the specimen has 2 segments (SI-B46-T20 + SI-B46-T22)" in err


@pytest.mark.parametrize(
    ("name", "message"),
    [
        ("SI-B46-T20", "is the name of an analytical segment"),
        ("gent-a", "is the name of an analytical segment"),
        ("../escape", "use 1-64 letters"),
        ("seg.csv", "use 1-64 letters"),
    ],
)
def test_add_refuses_names_that_would_shadow_or_escape(
    segment_run, tmp_path, capsys, name, message
):
    code, _, err = run(
        ["library", "add", segment_run.path, "--name", name, "--library", tmp_path], capsys
    )
    assert code == 2 and message in err
    assert list(tmp_path.iterdir()) == []


def test_add_does_not_overwrite_unless_asked(segment_run, tmp_path, capsys):
    argv = ["library", "add", segment_run.path, "--name", "twice", "--library", tmp_path]
    assert run(argv, capsys)[0] == 0
    code, _, err = run(argv, capsys)
    assert code == 2 and "already exists" in err and "--replace" in err
    assert run([*argv, "--replace"], capsys)[0] == 0
    code, out, _ = run(["library", "list", "--library", tmp_path], capsys)
    assert out.splitlines()[0].startswith("twice\tsimulated SI-B46-T20\t")


def test_a_failed_fit_names_the_run_file_not_a_temporary_csv(tmp_path):
    """The mean curve of a run that stopped before its valley cannot be fitted: the
    error names where the data came from."""
    from labrig.analysis.measured_library import add_measured
    from labrig.errors import InputError

    clean = analytical_segment("SI-B46-T20")
    v = np.linspace(0.0, 0.9 * clean.valley.v_ml, 400)  # still falling at the end
    with pytest.raises(InputError) as error:
        add_measured(
            "short",
            v,
            clean.pressure_kpa(v),
            clean.length_mm(v),
            {},
            tmp_path,
            where="runs/short.h5 (mean inflation curve)",
        )
    assert str(error.value).startswith("runs/short.h5 (mean inflation curve): ")
    assert "tmp" not in str(error.value).split(":")[0]
    assert not (tmp_path / "short.csv").exists()


def test_the_dry_run_warns_when_a_segment_run_stops_before_its_valley(tmp_path, capsys):
    """SI-B46-T20's valley is at 19.78 mL: infusing 15 mL makes a run that library add
    cannot use, 20.8 mL (the shipped protocol) one it can."""
    shipped = Path("protocols/segment_characterization.yaml").read_text(encoding="utf-8")
    for volume, warned in (("15", True), ("20.8", False)):
        protocol = tmp_path / f"p{volume}.yaml"
        protocol.write_text(shipped.replace("volume_ml: 20.8", f"volume_ml: {volume}"))
        code, out, err = run(["run", str(protocol), "--dry-run"], capsys)
        assert code == 0
        assert ("before SI-B46-T20's valley at 19.78 mL" in out + err) is warned
