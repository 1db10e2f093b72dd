"""Shared fixtures: simulated run files, written once per session (see simulated_runs)."""

import shutil

import pytest
from simulated_runs import killed_run, simulate_run, tiny_run


@pytest.fixture(scope="session")
def snap_run(tmp_path_factory):
    """B46-T20 + B46-T22 (the paper's Fig. 2 pair) inflated at 20 mL/min to 22 mL, five
    times, through water-like flow resistance (R = 1 kPa s/mL): the plant snaps through
    on inflation; pressure noise 0.3 kPa, the top of the issue's range."""
    path = tmp_path_factory.mktemp("runs") / "snap.h5"
    return simulate_run(path, ("B46-T20", "B46-T22"), volume_ml=22.0, noise_kpa=0.3, seed=11)


@pytest.fixture(scope="session")
def library_run(tmp_path_factory):
    """B44-T22 + B50-T20 in the slow limit (R = 0.05 kPa s/mL), where the plant follows
    the model's quasi-static path: one snap on inflation, one on deflation."""
    path = tmp_path_factory.mktemp("runs") / "library.h5"
    return simulate_run(
        path,
        ("B44-T22", "B50-T20"),
        volume_ml=36.0,
        resistance_kpa_s_per_ml=0.05,
        noise_kpa=0.1,
        seed=12,
    )


@pytest.fixture(scope="session")
def segment_run(tmp_path_factory):
    """A single segment, B46-T20, past its valley onto the stiffening wall; the third
    repetition faulted (so the mean is of repetitions 1, 2, 4 and 5)."""
    path = tmp_path_factory.mktemp("runs") / "segment.h5"
    statuses = ("complete", "complete", "faulted", "complete", "complete")
    return simulate_run(
        path, ("B46-T20",), volume_ml=20.8, noise_kpa=0.15, statuses=statuses, seed=13
    )


@pytest.fixture
def copy_of(tmp_path):
    """A private copy of a session run file, for tests that write to it."""

    def copy(run, name="copy.h5"):
        target = tmp_path / name
        shutil.copyfile(run.path, target)
        return target

    return copy


@pytest.fixture
def tiny_file(tmp_path):
    """A small complete run (2 repetitions of 2 mL, p = 5 v, l = 30 + v)."""
    return tiny_run(tmp_path / "tiny.h5")


@pytest.fixture
def killed_file(tmp_path):
    """A run file left by a SIGKILLed writer: flagged open, status running."""
    return killed_run(tmp_path)
