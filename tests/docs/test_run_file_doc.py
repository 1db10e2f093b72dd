"""The run file's reference names everything a real run file holds."""

import re
from pathlib import Path

import h5py

from labrig.analysis import analyse_run

PAGE = Path(__file__).resolve().parents[2] / "docs" / "reference" / "run-file.md"


def _names_in(path: Path) -> set[str]:
    """Every group and dataset name of the file, repetitions named as the page does."""
    names: set[str] = set()
    with h5py.File(path, "r") as f:
        f.visit(lambda name: names.add(re.sub(r"rep_\d+", "rep_01", name.rsplit("/", 1)[-1])))
    return names


def test_every_group_and_dataset_of_an_analysed_run_is_on_the_page(library_run, copy_of):
    path = copy_of(library_run)
    analyse_run(path)
    names = _names_in(path)
    # the analysis with its model comparison, and the camera's length series, are there
    assert {"analysis", "model", "matches", "rmse", "length", "x1"} <= names
    words = set(re.findall(r"[A-Za-z_][A-Za-z0-9_]*", PAGE.read_text(encoding="utf-8")))
    assert sorted(names - words) == []
