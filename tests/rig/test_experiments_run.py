"""The step experiments' protocols on the whole simulated rig: the technician's prompt
switches the plumbing, the reservoir's push triggers the snap, the load cell reads the
blocked actuator's force; and what compare --json reports from the files."""

from pathlib import Path

import h5py
import numpy as np
import pytest
from support.simrig import run_sim

from labrig.analysis.experiments import experiment_fields, force_for_run
from labrig.recording.run_reader import decode

PROTOCOLS = Path(__file__).parents[2] / "protocols"


def shortened(name: str, *replacements: tuple[str, str]) -> str:
    """A shipped protocol with a few values changed to keep the suite quick."""
    text = (PROTOCOLS / name).read_text()
    for old, new in replacements:
        assert old in text, old
        text = text.replace(old, new)
    return text


@pytest.mark.xdist_group("experiments")
def test_the_reservoir_step_triggers_the_snap_and_its_internal_flow(tmp_path):
    text = shortened("movie_s6.yaml", ("camera_fps: 30", "camera_fps: 0"))
    outcome = run_sim(tmp_path, text)
    assert outcome.result.status == "complete", outcome.result.reason
    with h5py.File(outcome.path) as run:
        events = run["entry/events"]
        kinds = [decode(k) for k in events["kind"][:]]
        t_events = events["time"][:]
        volumes = run["entry/simulation/segment_volumes"]
        t_v = volumes["time"][:]
        v = np.stack([volumes[f"v{i}"][:] for i in (1, 2, 3)], axis=1)
    assert kinds == ["prompt", "connect", "reservoir"]
    assert outcome.rig.simulation.plant.connected == "reservoir"
    # before the push, at rest on the reservoir: nothing flows between the segments
    t_connect, t_push = t_events[1], t_events[2]
    quiet = (t_v > t_connect) & (t_v < t_push)
    assert np.ptp(v[quiet], axis=0).max() < 0.01
    (step,) = experiment_fields(outcome.path, {})["steps"]
    assert step["volume_ml"] == 1.0
    # the 1 mL push moves several mL between the segments and drops the pressure
    assert step["internal_flow_ml"] > 5.0
    assert step["dp_kpa"] < -2.0
    assert 0.2 < step["actuation_time_s"] < 5.0
    # the total rose by what the reservoir pushed in, and by what the line's wall
    # compliance (0.002 mL/kPa) gave back as the pressure fell
    released = 0.002 * -step["dp_kpa"]
    assert v[-1].sum() - v[quiet][-1].sum() == pytest.approx(1.0 + released, abs=0.005)


@pytest.mark.xdist_group("experiments")
def test_the_blocked_actuators_force_follows_the_model_and_jumps_at_its_snap(tmp_path):
    # the SI's segments of the pair: one snap, at 15.8 mL, with a 1.35 N drop
    text = shortened(
        "blocked_force.yaml",
        ("{rate_ml_min: 5, volume_ml: 30}", "{rate_ml_min: 10, volume_ml: 19}"),
        ("segments: [B48-T30, B50-T20]", "segments: [SI-B48-T30, SI-B50-T20]"),
    )
    outcome = run_sim(tmp_path, text)
    assert outcome.result.status == "complete", outcome.result.reason
    force = force_for_run(outcome.path)
    assert force.rms_n < 0.5
    ((snap),) = force.transitions
    assert snap.force_model_n < -1.0
    assert snap.force_n == pytest.approx(snap.force_model_n, rel=0.1)
    fields = experiment_fields(outcome.path, {"transitions": [{"v_ml": snap.v_ml + 0.5}]})
    (transition,) = fields["transitions"]
    assert transition["force_model_n"] == pytest.approx(snap.force_model_n)
    assert fields["force"]["rms_n"] == pytest.approx(force.rms_n)
