"""The finished run and the small scan the Python API's tests read (helpers:
tests/support/api_runs.py)."""

import subprocess
import sys
from pathlib import Path

import pytest
from support.api_runs import record


@pytest.fixture(scope="session")
def quick_run(tmp_path_factory) -> Path:
    """A finished simulated run with its analysis stored (the runner stores it)."""
    return record(tmp_path_factory.mktemp("api") / "quick.h5", seed=3)


@pytest.fixture(scope="session")
def gent_scan(tmp_path_factory) -> Path:
    """Every pair of the three Gent membranes, by `labrig model scan` (one process)."""
    out = tmp_path_factory.mktemp("scan") / "gent.h5"
    command = [sys.executable, "-m", "labrig", "model", "scan", "--n", "2", "--library",
               "gent", "--workers", "1", "--out", str(out)]  # fmt: skip
    subprocess.run(command, check=True, capture_output=True)
    return out
