"""The ``live_run`` fixture: simulated runs with their live view (``liverun``)."""

from __future__ import annotations

from pathlib import Path

import pytest
from support.liverun import PROTOCOL, LiveRun


@pytest.fixture
def live_run(tmp_path):
    runs: list[LiveRun] = []

    def start(*extra: str, protocol: Path = PROTOCOL, speed: float = 10) -> LiveRun:
        run = LiveRun(protocol, tmp_path / f"run{len(runs)}.h5", *extra, speed=speed)
        runs.append(run)
        return run

    yield start
    for run in runs:
        run.stop()
