"""The simulated specimen is not the model: the rig file's ``sim.specimen`` is the truth
the plant is built from (its segments and its real-world behaviour), the protocol's
specimen stays the model the run is compared with, and the run file records the truth."""

import json
import textwrap

import pytest
import yaml
from support.simrig import run_sim

from labrig.analysis.runfile import load_run
from labrig.cli import main
from labrig.config.protocol import load_protocol
from labrig.config.rig_file import PumpConfig, RigConfig, SimConfig, SimSpecimen, load_rig_config
from labrig.errors import InputError
from labrig.rig.assembly import build_rig

# the demo's actuator inflated 30 mL, withdrawn 18, inflated 18 again: partial cycles
PARTIAL = textwrap.dedent(
    """\
    name: partial cycles
    specimen: {{segments: [{segments}], fittings_length_mm: 10}}
    rig: sim
    limits: {{max_pressure_kpa: 95, max_volume_ml: 45}}
    acquisition: {{pressure_rate_hz: 1000, camera_fps: 0}}
    steps:
      - zero_pressure: {{duration_s: 1}}
      - infuse: {{rate_ml_min: 60, volume_ml: 30}}
      - withdraw: {{rate_ml_min: 60, volume_ml: 18}}
      - infuse: {{rate_ml_min: 60, volume_ml: 18}}
    """
)
DEMO_SEGMENTS = "B48-T30, B50-T20"
SHORT_CYCLE = textwrap.dedent(
    """\
    name: one short cycle
    specimen: {segments: [B48-T30]}
    rig: sim
    limits: {max_pressure_kpa: 100, max_volume_ml: 20}
    acquisition: {pressure_rate_hz: 1000, camera_fps: 0}
    steps:
      - zero_pressure: {duration_s: 1}
      - infuse: {rate_ml_min: 60, volume_ml: 8}
      - withdraw: {rate_ml_min: 60, volume_ml: 8}
    """
)


def sim_config(**truth) -> RigConfig:
    specimen = SimSpecimen(**truth) if truth else None
    return RigConfig(pump=PumpConfig(port="emulator"), sim=SimConfig(specimen=specimen))


def test_the_partial_cycle_protocol_completes_with_a_whole_sensor(tmp_path):
    outcome = run_sim(tmp_path, PARTIAL.format(segments=DEMO_SEGMENTS))
    assert outcome.result.status == "complete", outcome.result.reason


def test_the_truth_as_run_is_in_the_run_file(tmp_path):
    outcome = run_sim(
        tmp_path,
        PARTIAL.format(segments=DEMO_SEGMENTS),
        config=sim_config(segments=["SI-B48-T30", "SI-B50-T20"], stiffness_factor=1.2),
    )
    assert outcome.result.status == "complete", outcome.result.reason
    as_run = yaml.safe_load(load_run(outcome.path).rig_config_text)
    truth = as_run["sim"]["specimen"]
    assert truth["segments"] == ["SI-B48-T30", "SI-B50-T20"]
    assert truth["stiffness_factor"] == 1.2
    # the default truth is recorded too: the protocol's own segments
    default = run_sim(tmp_path, PARTIAL.format(segments=DEMO_SEGMENTS), name="default.h5")
    as_run = yaml.safe_load(load_run(default.path).rig_config_text)
    assert as_run["sim"]["specimen"]["segments"] == ["B48-T30", "B50-T20"]


def compare_rmse(path, capsys) -> dict:
    with pytest.raises(SystemExit) as done:
        main(["compare", str(path), "--json"])
    assert done.value.code == 0
    return json.loads(capsys.readouterr().out)["rmse"]


def test_compare_shows_a_specimen_that_differs_from_its_model(tmp_path, capsys):
    """The same protocol on a specimen that is its model and on one that is 0.6 times as
    softer: both complete, and compare's pressure error is far larger on the second."""
    text = SHORT_CYCLE
    agreeing = run_sim(tmp_path, text, name="agreeing.h5")
    differing = run_sim(
        tmp_path, text, name="differing.h5", config=sim_config(stiffness_factor=0.6)
    )
    assert agreeing.result.status == differing.result.status == "complete"
    agree = compare_rmse(agreeing.path, capsys)["inflate_pressure_kpa"]
    differ = compare_rmse(differing.path, capsys)["inflate_pressure_kpa"]
    assert differ > 10 * agree and differ > 5.0, (agree, differ)


def test_a_protocol_whose_segments_no_library_holds_needs_the_truth(tmp_path):
    path = tmp_path / "p.yaml"
    path.write_text(PARTIAL.format(segments=DEMO_SEGMENTS))
    protocol = load_protocol(path).protocol
    unknown = protocol.model_copy(
        update={"specimen": protocol.specimen.model_copy(update={"segments": ["LAB-S37"]})}
    )
    with pytest.raises(InputError, match=r"'LAB-S37'.*give the rig file's sim\.specimen") as error:
        build_rig(unknown, sim_config())
    assert "\n" not in str(error.value)


@pytest.mark.parametrize(
    ("key", "value", "allowed"),
    [
        ("stiffness_factor", "0", "greater than or equal to 0.1"),
        ("hysteresis_kpa", "-1", "greater than or equal to 0"),
        ("first_cycle_factor", "0.5", "greater than or equal to 1"),
        ("air_ml", "200", "less than or equal to 100"),
        ("leak_fraction", "1.0", "less than or equal to 0.9"),
        ("burst_at_ml", "0", "greater than 0"),
        ("stifness_factor", "2", "unknown key"),
    ],
)
def test_the_truths_keys_are_checked_with_the_key_and_the_range(tmp_path, key, value, allowed):
    (tmp_path / "rigs").mkdir()
    (tmp_path / "rigs" / "sim.yaml").write_text(
        f"pump: {{port: emulator}}\nsim:\n  specimen:\n    {key}: {value}\n"
    )
    path = tmp_path / "p.yaml"
    path.write_text(SHORT_CYCLE.replace("rig: sim", "rig: rigs/sim.yaml"))
    with pytest.raises(InputError, match=rf"sim\.yaml: line 4: sim\.specimen\.{key}: .*{allowed}"):
        load_rig_config(load_protocol(path))


def test_a_burst_at_12_ml_faults_the_run_before_13_ml_are_infused(tmp_path):
    outcome = run_sim(
        tmp_path, PARTIAL.format(segments=DEMO_SEGMENTS), config=sim_config(burst_at_ml=12.0)
    )
    assert outcome.result.status == "faulted"
    assert outcome.result.reason.startswith("the specimen lost pressure")
    emulator = outcome.rig.simulation.emulator
    stopped_ml = emulator.net_volume_ml(outcome.end_s)
    assert emulator.net_volume_ml(outcome.end_s + 30.0) == stopped_ml  # standing still
    assert 12.0 < stopped_ml <= 13.0


def test_a_leak_is_reported_as_a_leak_when_the_specimen_is_emptied(tmp_path):
    """10 % of 8 mL lost: withdrawn, the specimen is empty with 0.8 mL still counted."""
    outcome = run_sim(tmp_path, SHORT_CYCLE, config=sim_config(leak_fraction=0.1))
    assert outcome.result.status == "faulted"
    assert outcome.result.reason.startswith("the specimen leaks")
    emulator = outcome.rig.simulation.emulator
    assert 0.5 <= emulator.net_volume_ml(outcome.end_s + 30.0) <= 0.8
