"""A rate that validates can start: the slowest pressure rate and camera a protocol
accepts, and the fastest pressure rate the DAQ takes on two inputs, run on the
simulated rig; one more is refused by the dry run, before anything moves."""

import textwrap

import h5py
import numpy as np
import pytest
from support.simrig import run_sim

from labrig.cli import main
from labrig.config.protocol import MIN_CAMERA_FPS, MIN_PRESSURE_RATE_HZ

SLOW = textwrap.dedent(
    f"""\
    name: slowest rates
    specimen: {{segments: [B46-T20], fittings_length_mm: 10}}
    rig: sim
    limits: {{max_pressure_kpa: 95, max_volume_ml: 10}}
    acquisition: {{pressure_rate_hz: {MIN_PRESSURE_RATE_HZ:g}, camera_fps: {MIN_CAMERA_FPS:g}}}
    steps:
      - zero_pressure: {{duration_s: 1}}
      - infuse: {{rate_ml_min: 60, volume_ml: 3}}
      - hold: {{seconds: 5}}
    """
)

BLOCKED = textwrap.dedent(
    """\
    name: fastest rate on two inputs
    specimen: {{segments: [B48-T30, B50-T20], fittings_length_mm: 10, length: blocked}}
    rig: sim
    limits: {{max_pressure_kpa: 95, max_volume_ml: 10}}
    acquisition: {{pressure_rate_hz: {rate}}}
    steps:
      - zero_pressure: {{duration_s: 0.2}}
      - infuse: {{rate_ml_min: 60, volume_ml: 0.5}}
    """
)


def test_the_slowest_pressure_rate_and_camera_complete(tmp_path):
    outcome = run_sim(tmp_path, SLOW)
    assert outcome.result.status == "complete", outcome.result.reason
    with h5py.File(outcome.path, "r") as f:
        pressure_t = f["entry/repetitions/rep_01/pressure/time"][()]
        length_t = f["entry/repetitions/rep_01/length/time"][()]
    # 8 s at 10 Hz, and at 1 frame a second once the camera's 5 warm-up frames are gone
    assert np.median(np.diff(pressure_t)) == pytest.approx(0.1, rel=0.01)
    assert len(length_t) >= 3 and np.all(np.diff(length_t) == pytest.approx(1.0, rel=0.01))


def test_the_fastest_rate_on_the_sensor_and_a_load_cell_starts(tmp_path):
    outcome = run_sim(tmp_path, BLOCKED.format(rate=24000))
    assert outcome.result.status == "complete", outcome.result.reason


def test_beyond_it_the_dry_run_refuses(tmp_path, capsys):
    path = tmp_path / "p.yaml"
    path.write_text(BLOCKED.format(rate=24001))
    with pytest.raises(SystemExit) as exited:
        main(["run", str(path), "--dry-run"])
    out, _ = capsys.readouterr()
    assert exited.value.code == 2
    assert (
        "error: acquisition.pressure_rate_hz = 24001 on 2 inputs (the sensor, the load cell "
        "(specimen.length: blocked)) is 48002 S/s; the USB-6009 samples at most 48000 S/s in "
        "total: at most 24000 Hz"
    ) in out
