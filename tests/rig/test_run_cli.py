"""`labrig run` refuses bad protocols with a clear message before anything moves, and
the dry run answers without a rig."""

import datetime as dt
import os
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

from labrig.cli import main

GOOD = textwrap.dedent(
    """\
    name: cli test
    specimen: {segments: [SI-B48-T30, SI-B50-T20]}
    rig: sim
    limits: {max_pressure_kpa: 95, max_volume_ml: 45}
    acquisition: {pressure_rate_hz: 1000, camera_fps: 0}
    steps:
      - zero_pressure: {}
      - infuse: {rate_ml_min: 40, volume_ml: 10}
      - withdraw: {rate_ml_min: 40, volume_ml: 10}
    """
)


def run_cli(args, capsys):
    with pytest.raises(SystemExit) as exited:
        main(args)
    out, err = capsys.readouterr()
    return exited.value.code, out, err


@pytest.mark.parametrize(
    ("old", "new", "expected"),
    [
        (
            "rate_ml_min: 40, volume_ml: 10}\n  - withdraw",
            "rate_ml_min: fast, volume_ml: 10}\n  - withdraw",
            "steps[1].infuse.rate_ml_min: Input should be a valid number",
        ),
        ("camera_fps: 0", "camera_fps: 0, gain: 2", "acquisition.gain: unknown key"),
        (
            "rate_ml_min: 40, volume_ml: 10}\n  - withdraw",
            "rate_ml_min: -4, volume_ml: 10}\n  - withdraw",
            "rate_ml_min: Input should be greater than or equal to 0.000000001",
        ),
        (
            "rate_ml_min: 40, volume_ml: 10}\n  - withdraw",
            "rate_ml_min: 400, volume_ml: 10}\n  - withdraw",
            "runs at 0.000124 to 128.9 mL/min",
        ),
        ("max_volume_ml: 45", "max_volume_ml: 5", "above limits.max_volume_ml = 5 mL"),
        ("[SI-B48-T30, SI-B50-T20]", "[SI-B48-T30, SI-B51-T20]", "SI-B51-T20"),
    ],
)
def test_bad_protocols_are_refused_before_the_pump_moves(tmp_path, capsys, old, new, expected):
    assert old in GOOD
    protocol = tmp_path / "bad.yaml"
    protocol.write_text(GOOD.replace(old, new))
    out_file = tmp_path / "run.h5"
    code, out, err = run_cli(["run", str(protocol), "--out", str(out_file)], capsys)
    assert code == 2
    assert expected in out + err
    assert "Traceback" not in out + err
    assert not out_file.exists()  # nothing was created, nothing moved


def test_dry_run_summarises_and_moves_nothing(tmp_path, capsys):
    protocol = tmp_path / "p.yaml"
    protocol.write_text(GOOD)
    code, out, _ = run_cli(["run", str(protocol), "--dry-run"], capsys)
    assert code == 0
    assert "duration    0.5 min (1 repetitions)" in out
    assert "model peak" in out and "(limit 95 kPa)" in out
    assert not Path("runs").exists() or not any(Path("runs").glob("*cli-test*"))


def test_run_cli_writes_a_complete_file(tmp_path):
    protocol = tmp_path / "p.yaml"
    protocol.write_text(GOOD)
    out_file = tmp_path / "run.h5"
    result = subprocess.run(
        [
            sys.executable,
            "-m",
            "labrig",
            "run",
            str(protocol),
            "--out",
            str(out_file),
            "--speed",
            "100",
        ],
        capture_output=True,
        text=True,
        timeout=120,
        # the console's width is the terminal's or 80: the message on one line, also
        # for an xdist worker's longer tmp_path
        env={**os.environ, "COLUMNS": "500"},
    )
    assert result.returncode == 0, result.stderr
    assert f"complete: {out_file}" in result.stderr
    assert out_file.exists()


def test_dry_run_on_a_rig_file_shows_the_backstop_and_what_the_pump_can_do(tmp_path, capsys):
    (tmp_path / "rigs").mkdir()
    rig = "pump: {port: /dev/ttyACM0, infuse_only: true, syringe: {diameter_mm: 27.6}}\n"
    (tmp_path / "rigs" / "bench.yaml").write_text(rig)
    protocol = tmp_path / "p.yaml"
    protocol.write_text(GOOD.replace("rig: sim", "rig: rigs/bench.yaml"))
    code, out, err = run_cli(["run", str(protocol), "--dry-run"], capsys)
    assert code == 2  # refused before any device is opened
    assert "pump        infuse only (pump.infuse_only)" in out
    assert "error: steps[2].withdraw: the rig's pump is infuse-only" in out + err
    # 75 lbf over 598.3 mm^2 is 557.6 kPa (by hand); 1.5 x 95 kPa needs 26 % of it.
    assert "force limit 100 % of 333.6 N on the 27.6 mm syringe (598.3 mm²)" in out
    assert "stalls above 557.6 kPa (pressure limit 95 kPa)" in out
    assert "pump.force_limit_pct: 26 stalls it at 145 kPa" in out
    (tmp_path / "rigs" / "bench.yaml").write_text(
        rig.replace("infuse_only: true", "force_limit_pct: 26")
    )
    code, out, _ = run_cli(["run", str(protocol), "--dry-run"], capsys)
    assert code == 0
    assert "pump        infuses and withdraws" in out and "stalls above 145.0 kPa" in out
    assert "warning" not in out


def test_the_default_run_file_gets_a_counter_when_its_name_is_taken(tmp_path, monkeypatch):
    """Two runs of one protocol in one second: the second default name gets -2, also
    while the first has not created its file yet (its name is reserved), and a finished
    run's name is never reused; an explicit --out keeps refusing an existing file."""
    from labrig.cli.run import default_out_path
    from labrig.errors import InputError
    from labrig.recording.run_file_lock import claim_out_path, drop_reservation, lock_path
    from tests.support.simulated_runs import tiny_run

    monkeypatch.chdir(tmp_path)
    second = dt.datetime(2026, 12, 5, 12, 0, 7)
    first = default_out_path("cli test", second)
    assert first == Path("runs/20261205_120007_cli-test.h5")
    assert lock_path(first).exists()  # reserved before the rig is built
    assert default_out_path("cli test", second) == first.with_name(f"{first.stem}-2.h5")
    tiny_run(first)  # the first run wrote its file (its writer let the sidecar go)
    drop_reservation(first.with_name(f"{first.stem}-2.h5"))  # the second never ran
    assert not lock_path(first).exists()
    assert default_out_path("cli test", second) == first.with_name(f"{first.stem}-2.h5")
    with pytest.raises(InputError, match="a run file is already there"):
        claim_out_path(first, overwrite=False)
