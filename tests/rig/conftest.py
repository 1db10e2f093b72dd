"""The demo protocol's simulated run, made once for every test of it."""

import pytest
from support.simrig import DEMO, run_sim


@pytest.fixture(scope="session")
def demo(tmp_path_factory):
    return run_sim(tmp_path_factory.mktemp("demo"), DEMO.read_text(), seed=0)
