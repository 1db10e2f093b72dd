"""The demo protocol's simulated run, made once for every test of it."""

from pathlib import Path

import pytest
from simrig import run_sim

DEMO = Path(__file__).parents[2] / "protocols" / "demo.yaml"


@pytest.fixture(scope="session")
def demo(tmp_path_factory):
    return run_sim(tmp_path_factory.mktemp("demo"), DEMO.read_text(), seed=0)
