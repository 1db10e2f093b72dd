"""The tutorial "characterising new segments" runs as written: every ``labrig`` command of
its bash blocks, in order, in a copy of its folder, on the simulated rig (virtual
clock). What it says came out is checked against the simulated truth, which no command
is told: the measured peaks against the library segments behind the labels, and the
pair's snap against its prediction from the measured segments."""

import json
import re
import shlex
import shutil
from pathlib import Path

import h5py
import pytest

from labrig.cli import main
from labrig.model.segments.catalog import analytical_segment, load_segment

REPO = Path(__file__).resolve().parents[2]
PAGE = REPO / "docs" / "tutorials" / "characterising-new-segments.md"
FOLDER = REPO / "docs" / "tutorials" / "new-segments"
TRUTH = {"LAB-S1": "B48-T30", "LAB-S2": "B50-T20", "LAB-S3": "B46-T26"}


def blocks(kind: str) -> list[str]:
    return re.findall(rf"```{kind}\n(.*?)```", PAGE.read_text(encoding="utf-8"), re.S)


def run(args, capsys) -> str:
    with pytest.raises(SystemExit) as exited:
        main(args)
    out, err = capsys.readouterr()
    assert exited.value.code in (0, None), f"labrig {shlex.join(args)}: {out}{err}"
    return out + err


def words(text: str) -> str:
    """Text with its runs of spaces as one (a table's padding follows the terminal)."""
    return "\n".join(" ".join(line.split()) for line in text.splitlines())


def test_the_files_shown_are_the_tutorials_files():
    protocol, rig = blocks("yaml")
    assert protocol == (FOLDER / "lab-s1.yaml").read_text(encoding="utf-8")
    assert rig == (FOLDER / "rigs" / "lab-s1.yaml").read_text(encoding="utf-8")
    for label, truth in TRUTH.items():
        rig_file = FOLDER / "rigs" / f"{label.lower()}.yaml"
        assert f"sim: {{specimen: {{segments: [{truth}]}}}}" in rig_file.read_text()


def test_the_tutorial_runs_as_written(tmp_path, monkeypatch, capsys):
    work = tmp_path / "new-segments"
    shutil.copytree(FOLDER, work)
    monkeypatch.chdir(work)
    monkeypatch.delenv("LABRIG_LIBRARY", raising=False)
    monkeypatch.setenv("COLUMNS", "100")
    commands = [
        shlex.split(line)[1:]
        for block in blocks("bash")
        for line in block.splitlines()
        if line.startswith("labrig ")
    ]
    assert len(commands) == 13
    printed = {shlex.join(args): run(args, capsys) for args in commands}
    # every line the page shows was printed (but its "..." for lines left out)
    everything = words("\n".join(printed.values()))
    shown = [words(line) for block in blocks("text") for line in block.splitlines()]
    missing = [line for line in shown if line not in ("", "...") and line not in everything]
    assert missing == []

    # three runs with no model, recorded as such
    for label in TRUTH:
        with h5py.File(work / "runs" / f"{label.lower()}.h5", "r") as f:
            assert f["entry/status"][()].rstrip(b"\0") == b"complete"
            assert f["entry/specimen_model"][()] == b"none"
    assert "no model peak" in printed["run lab-s1.yaml --dry-run"]

    # each measured segment is the segment behind its label, within what the page says
    for label, truth in TRUTH.items():
        measured = load_segment(label, library_dir=work / "library")
        expected = analytical_segment(truth)
        assert measured.peak.p_kpa == pytest.approx(expected.peak.p_kpa, abs=0.06)
        assert measured.peak.v_ml == pytest.approx(expected.peak.v_ml, abs=0.11)

    # the pair snaps where its measured segments predicted
    answer = json.loads(run(["compare", "runs/pair.h5", "--json"], capsys))  # no stderr
    [snap] = [
        t for t in answer["paper_transitions"] if t["type"] == "snap" and t["phase"] == "inflate"
    ]
    assert snap["v_meas_ml"] == pytest.approx(snap["v_ml"], abs=0.3)
    assert snap["dp_meas_kpa"] == pytest.approx(snap["dp_kpa"], rel=0.1)
    assert snap["dl_meas_mm"] == pytest.approx(snap["dl_mm"], rel=0.1)
    assert answer["rmse"]["inflate_pressure_kpa"] < 3.0
    assert "snap (2,1)    23.96   23.86  -0.10" in printed["compare runs/pair.h5"]
