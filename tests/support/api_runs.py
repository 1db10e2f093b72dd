"""Run files for the Python API's tests, recorded for real by ``labrig run --sim``.

Plain helpers live here, not in tests/api/conftest.py: another folder's conftest can stand
first on sys.path, so ``from conftest import ...`` would find the wrong one.
"""

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


def cli(argv, capsys) -> tuple[int, str, str]:
    """(exit code, stdout, stderr) of ``labrig ARGV`` through the real entry point."""
    with pytest.raises(SystemExit) as exited:
        main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return exited.value.code, out, err
