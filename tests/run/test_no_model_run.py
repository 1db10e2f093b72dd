"""A specimen with no model (``specimen.model: none``) validates, dry-runs, runs, is
recorded as having had none, is analysed and compared without one, and becomes a
measured segment the model can then use."""

import json
import textwrap

import h5py
import pytest

from labrig.cli import main

NO_MODEL = textwrap.dedent(
    """\
    name: characterise {label}
    specimen: {{segments: [{label}], model: none, fittings_length_mm: 10}}
    rig: {rig}
    limits: {{max_pressure_kpa: 95, max_volume_ml: 25}}
    acquisition: {{pressure_rate_hz: 200, camera_fps: 2}}
    steps:
      - zero_pressure: {{duration_s: 1}}
      - repeat:
          times: 2
          steps:
            - infuse: {{rate_ml_min: 60, volume_ml: 18.3}}
            - withdraw: {{rate_ml_min: 60, volume_ml: 18.3}}
    analysis: {{average_last: 1}}
    """
)


def run_cli(args, capsys):
    with pytest.raises(SystemExit) as exited:
        main([str(a) for a in args])
    out, err = capsys.readouterr()
    return exited.value.code, out, err


def write(tmp_path, label="LAB-S37", rig="sim", *, model=True):
    text = NO_MODEL.format(label=label, rig=rig)
    if not model:
        text = text.replace(", model: none", "")
    path = tmp_path / "p.yaml"
    path.write_text(text)
    return path


def test_a_specimen_with_no_model_validates(tmp_path, capsys):
    code, out, err = run_cli(["protocol", "validate", write(tmp_path)], capsys)
    assert code == 0
    assert out.endswith("at most 18.3 mL in the specimen; no model (specimen.model: none)\n")
    assert err == ""


@pytest.mark.parametrize("rig", ["sim", "rigs/bench.yaml"])
def test_the_dry_run_says_there_is_no_model_peak(tmp_path, capsys, rig):
    """On the simulated rig and on a real rig's file (the dry run opens no device)."""
    (tmp_path / "rigs").mkdir()
    (tmp_path / "rigs" / "bench.yaml").write_text(
        "pump: {port: /dev/ttyACM0, force_limit_pct: 26}\n"
    )
    code, out, err = run_cli(["run", write(tmp_path, rig=rig), "--dry-run"], capsys)
    assert code == 0, out + err
    assert "  specimen    LAB-S37 (labels: no model)\n" in out
    assert "  duration    1.2 min (2 repetitions)\n" in out
    assert "at most 18.3 mL in the specimen (limit 25 mL)" in out
    assert (
        "  pressure    no model peak: the specimen has no model (specimen.model: none); the "
        "pressure limit 95 kPa and the interlocks guard the run\n"
    ) in out
    assert "unknown segment" not in out + err and "warning" not in out + err


def test_a_lab_label_without_model_none_is_refused_with_the_spelling(tmp_path, capsys):
    code, out, _ = run_cli(["run", write(tmp_path, model=False), "--dry-run"], capsys)
    assert code == 2
    [error] = [line for line in out.splitlines() if line.startswith("error: ")]
    assert error.startswith("error: specimen.segments[0]: unknown segment 'LAB-S37': ")
    assert error.endswith(
        "a specimen nothing models yet (one to characterise) has specimen.model: none, and "
        "its segments' names are then labels"
    )


def test_a_misspelt_library_name_is_caught_both_ways(tmp_path, capsys):
    """With a model the run is refused and told what was meant; with model: none the
    label runs, and validation and the dry run warn that it looks like a typo."""
    code, out, _ = run_cli(["run", write(tmp_path, "B46-T2O", model=False), "--dry-run"], capsys)
    assert code == 2
    assert "unknown segment 'B46-T2O'" in out and "did you mean 'B46-T20'? " in out

    code, out, err = run_cli(["protocol", "validate", write(tmp_path, "B46-T2O")], capsys)
    assert code == 0
    assert err.startswith("warning: specimen.segments[0] 'B46-T2O' looks like 'B46-T20' misspelt")
    code, out, _ = run_cli(["run", write(tmp_path, "B46-T2O"), "--dry-run"], capsys)
    assert code == 0
    assert "warning: specimen.segments[0] 'B46-T2O' looks like 'B46-T20' misspelt" in out


TRUTH = "pump: {port: emulator}\nsim: {specimen: {segments: [B46-T20]}}\n"


def test_the_simulated_rig_needs_the_truth_of_a_specimen_with_no_model(tmp_path, capsys):
    """Even a label that names a library segment: with no model, it is only a label."""
    (tmp_path / "rigs").mkdir()
    (tmp_path / "rigs" / "sim.yaml").write_text("pump: {port: emulator}\nsim: {}\n")
    protocol = write(tmp_path, "B46-T20", rig="rigs/sim.yaml")
    code, _, err = run_cli(["run", protocol, "--out", tmp_path / "r.h5"], capsys)
    assert code == 2
    assert err == (
        "error: the simulated rig cannot know what the specimen is: specimen.model: none "
        "makes its segments labels; give the rig file's sim.specimen.segments, the segments "
        "the simulated specimen really is (library names or CSV paths)\n"
    )
    assert not (tmp_path / "r.h5").exists()


@pytest.fixture(scope="module")
def no_model_run(tmp_path_factory):
    """A run of a specimen with no model on the simulated rig, through `labrig run`;
    the rig file's sim.specimen says the specimen labelled LAB-S37 is B46-T20."""
    folder = tmp_path_factory.mktemp("no-model")
    (folder / "rigs").mkdir()
    (folder / "rigs" / "truth.yaml").write_text(TRUTH)
    protocol = write(folder, rig="rigs/truth.yaml")
    out = folder / "run.h5"
    with pytest.raises(SystemExit) as exited:
        main(["run", str(protocol), "--out", str(out)])
    assert exited.value.code == 0
    return out


def test_the_run_file_says_it_had_no_model(no_model_run):
    with h5py.File(no_model_run, "r") as f:
        assert f["entry/specimen_model"][()] == b"none"
        assert f["entry/status"][()].rstrip(b"\0") == b"complete"
        notes = [note.decode() for note in f["entry/analysis/notes"][()]]
        assert "model" not in f["entry/analysis"]
    assert [note for note in notes if note.startswith("no model to compare with")] == [
        "no model to compare with: the specimen has no model (specimen.model: none); "
        "labrig compare RUN --segments SEG compares it with segments you name"
    ]


def test_the_analysis_says_in_one_line_there_is_no_model(no_model_run, capsys):
    code, out, err = run_cli(["show", no_model_run], capsys)
    assert code == 0
    assert "labels, no model" in out
    notes = [line for line in out.splitlines() if line.startswith("note: no model")]
    assert notes, out
    code, out, err = run_cli(["compare", no_model_run], capsys)
    assert code == 0
    assert out == (
        f"{no_model_run}: no model to compare with: the specimen has no model "
        "(specimen.model: none); labrig compare RUN --segments SEG compares it with "
        "segments you name\n"
    )
    assert "Traceback" not in err


def test_compare_json_without_a_model_says_so_in_a_field(no_model_run, capsys):
    code, out, _ = run_cli(["compare", no_model_run, "--json"], capsys)
    assert code == 0
    answer = json.loads(out)
    assert answer["no_model"].startswith("no model to compare with")
    assert answer["rmse"] == {
        "inflate_pressure_kpa": None,
        "inflate_length_mm": None,
        "deflate_pressure_kpa": None,
        "deflate_length_mm": None,
    }
    assert answer["transitions"] == answer["paper_transitions"] == answer["unpredicted"] == []


def test_segments_named_on_the_command_line_are_compared(no_model_run, capsys):
    """The simulated specimen is B46-T20: compared with it, the pressure agrees."""
    code, out, _ = run_cli(["compare", no_model_run, "--json", "--segments", "B46-T20"], capsys)
    assert code == 0
    answer = json.loads(out)
    assert "no_model" not in answer
    assert answer["rmse"]["inflate_pressure_kpa"] < 3.0


def test_library_add_makes_it_a_measured_segment_the_model_uses(
    no_model_run, tmp_path, capsys, monkeypatch
):
    library = tmp_path / "lib"
    code, out, err = run_cli(
        ["library", "add", no_model_run, "--name", "LAB-S37", "--library", library], capsys
    )
    assert code == 0, err
    assert out.startswith(f"{library}/LAB-S37.csv: measured segment 'LAB-S37'")
    monkeypatch.setenv("LABRIG_LIBRARY", str(library))
    from labrig.model.segments.catalog import analytical_segment, load_segment

    # the measured curve is the simulated specimen's, which the analysis never saw
    measured, truth = load_segment("LAB-S37"), analytical_segment("B46-T20")
    assert measured.peak.p_kpa == pytest.approx(truth.peak.p_kpa, abs=1.0)
    assert measured.peak.v_ml == pytest.approx(truth.peak.v_ml, abs=0.5)
    code, out, err = run_cli(["model", "path", "LAB-S37", "B42-T24"], capsys)
    assert code == 0, err
    assert "LAB-S37" in out


def test_the_live_page_is_told_there_is_no_model(tmp_path):
    from labrig.config.protocol import load_protocol
    from labrig.live.model import prediction_json

    answer = prediction_json(load_protocol(write(tmp_path)).protocol)
    assert answer == {
        "ready": True,
        "segments": ["LAB-S37"],
        "error": "the specimen has no model (specimen.model: none): its segments are labels",
    }
