"""Run files for the Python API's tests, recorded for real by ``labrig run --sim``."""

from pathlib import Path

import pytest

from labrig.cli import main

REPO = Path(__file__).resolve().parents[2]
# the tutorial's protocol: the demo's pair, two repetitions, light acquisition
QUICK_PROTOCOL = REPO / "docs/tutorials/quick-demo.yaml"


def record(out: Path, seed: int) -> Path:
    """``labrig run QUICK_PROTOCOL --sim --seed SEED --out OUT`` in this process."""
    with pytest.raises(SystemExit) as exited:
        main(["run", str(QUICK_PROTOCOL), "--sim", "--seed", str(seed), "--out", str(out)])
    assert exited.value.code == 0
    return out


@pytest.fixture(scope="session")
def quick_run(tmp_path_factory) -> Path:
    """A finished simulated run with its analysis stored (the runner stores it)."""
    return record(tmp_path_factory.mktemp("api") / "quick.h5", seed=3)


def cli(argv, capsys) -> tuple[int, str, str]:
    """(exit code, stdout, stderr) of ``labrig ARGV`` through the real entry point."""
    with pytest.raises(SystemExit) as exited:
        main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return exited.value.code, out, err
