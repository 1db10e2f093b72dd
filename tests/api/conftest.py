"""The finished run the Python API's tests read (helpers: tests/support/api_runs.py)."""

from pathlib import Path

import pytest
from support.api_runs import record


@pytest.fixture(scope="session")
def quick_run(tmp_path_factory) -> Path:
    """A finished simulated run with its analysis stored (the runner stores it)."""
    return record(tmp_path_factory.mktemp("api") / "quick.h5", seed=3)
