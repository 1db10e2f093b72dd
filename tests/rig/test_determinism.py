"""The simulated rig on virtual time: the same protocol and seed give bitwise the same
data on a busy host, and nothing is lost by construction (exact sample, poll and frame
counts; a hold is its length; identical repetitions last identically long)."""

import subprocess
import sys
import time

import numpy as np
import pytest
from support.simrig import DEMO, run_sim, short_protocol

from labrig.recording.run_reader import open_run, read_log

SERIES = ("pressure", "pump", "length")


def recorded(path):
    with open_run(path) as run:
        return {(rep, name): read_log(run, rep, name) for rep in (1, 2, 3) for name in SERIES}


@pytest.mark.soak  # the default run: test_speed_paces_the_run_without_changing_its_data
def test_same_seed_same_data_beside_two_cpu_burners(demo, tmp_path):
    # each burns a core until killed, or until this process is gone (a killed pytest
    # must not leave them burning)
    burn = "import os\nparent = os.getppid()\nwhile os.getppid() == parent: pass"
    burners = [subprocess.Popen([sys.executable, "-c", burn]) for _ in range(2)]
    try:
        again = run_sim(tmp_path, DEMO.read_text(), seed=0)
    finally:
        for burner in burners:
            burner.kill()
            burner.wait()
    first, second = recorded(demo.path), recorded(again.path)
    assert first.keys() == second.keys()
    for key, log in first.items():
        other = second[key]
        assert np.array_equal(log.time_s, other.time_s), key  # bitwise, not approx
        for field, values in log.fields.items():
            nan_ok = values.dtype.kind == "f"
            assert np.array_equal(values, other.fields[field], equal_nan=nan_ok), (key, field)


def test_another_seed_gives_other_noise(demo, tmp_path):
    # one short repetition: its first 5 s are the demo's first 5 s of inflation
    text = DEMO.read_text().replace("times: 3", "times: 1").replace("volume_ml: 38", "volume_ml: 6")
    other = run_sim(tmp_path, text, seed=1)
    a, b = recorded(demo.path), None
    with open_run(other.path) as run:
        b = read_log(run, 1, "pressure")
        assert "seed: 1" in run["entry/rig_config"][()].decode()
    n = min(len(b), 5000)
    assert not np.array_equal(a[(1, "pressure")].fields["value"][:n], b.fields["value"][:n])
    # the timeline is the same: the seed changes the noise, not the clock
    assert np.array_equal(a[(1, "pressure")].time_s[:n], b.time_s[:n])


def test_every_sample_poll_and_frame_is_kept(demo):
    with open_run(demo.path) as run:
        reps = run["entry/repetitions"]
        t_start, t_end = reps["t_start"][:], reps["t_end"][:]
    for (rep, name), log in recorded(demo.path).items():
        dt = np.diff(log.time_s)
        if name == "pressure":
            assert dt == pytest.approx(np.full(len(dt), 0.001), abs=1e-9)  # 1 kHz
            during = (log.time_s >= t_start[rep - 1]) & (log.time_s < t_end[rep - 1])
            assert np.count_nonzero(during) == pytest.approx(124_000, abs=1)  # 124 s, 1 kHz
            # the last repetition holds the samples up to the stop as well (read from
            # the DAQ's buffer as acquisition stops), the others none beyond their end
            after = len(log) - np.count_nonzero(during)
            assert (after > 0) if rep == 3 else (after <= 1)
        elif name == "length":
            assert dt == pytest.approx(np.full(len(dt), 1 / 30), abs=1e-9)  # 30 fps, no gap
            assert log.fields["ok"].all()
        else:
            # every 0.2 s, and once more when a motion starts (after its run command,
            # possibly at the instant of a regular poll); two motions per repetition
            assert np.all(dt <= 0.2 + 1e-9) and np.all(dt >= 0)
            assert np.sum(dt < 0.2 - 1e-9) <= 2


def test_identical_repetitions_last_identically_and_a_hold_is_its_length(demo):
    with open_run(demo.path) as run:
        reps = run["entry/repetitions"]
        durations = reps["t_end"][:] - reps["t_start"][:]
    # infuse 38 mL at 40 mL/min (57 s), hold 5 s, withdraw (57 s), hold 5 s
    assert durations == pytest.approx([124.0] * 3, abs=1e-9)
    emulator = demo.rig.simulation.emulator
    with open_run(demo.path) as run:
        pump = read_log(run, 2, "pump")
    t = pump.time_s
    volume = np.array([emulator.net_volume_ml(x) for x in t])
    # the plunger stands at 38 mL from the target stop until the withdrawal starts
    at_top = t[np.abs(volume - 38.0) < 1e-9]
    assert at_top[-1] - at_top[0] == pytest.approx(5.0, abs=1e-9)


def test_speed_paces_the_run_without_changing_its_data(tmp_path):
    text = short_protocol()
    wall0 = time.monotonic()
    paced = run_sim(tmp_path, text, speed=50.0, name="paced.h5")
    paced_wall_s = time.monotonic() - wall0
    unpaced = run_sim(tmp_path, text, name="unpaced.h5")
    with open_run(paced.path) as a, open_run(unpaced.path) as b:
        for rep in (1, 2):
            for name in SERIES:
                x, y = read_log(a, rep, name), read_log(b, rep, name)
                assert np.array_equal(x.time_s, y.time_s), (rep, name)
                assert np.array_equal(x.fields["value"], y.fields["value"], equal_nan=True)
    # pacing only ever waits: 85 s of rig time cannot take less than 85 / 50 s of wall
    assert paced.end_s > 80.0 and paced_wall_s >= paced.end_s / 50.0 - 0.3
