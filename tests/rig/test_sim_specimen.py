"""The simulated specimen is not the model: the rig file's ``sim.specimen`` is the truth
the plant is built from (its segments and its real-world behaviour), the protocol's
specimen stays the model the run is compared with, and the run file records the truth."""

import textwrap

import pytest
import yaml
from support.simrig import run_sim

from labrig.analysis.runfile import load_run
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


def test_the_truth_as_run_is_in_the_run_file(tmp_path):
    outcome = run_sim(
        tmp_path,
        SHORT_CYCLE,
        config=sim_config(segments=["SI-B48-T30"], stiffness_factor=1.02),
    )
    assert outcome.result.status == "complete", outcome.result.reason
    as_run = yaml.safe_load(load_run(outcome.path).rig_config_text)
    truth = as_run["sim"]["specimen"]
    assert truth["segments"] == ["SI-B48-T30"]
    assert truth["stiffness_factor"] == 1.02
    # the default truth is recorded too: the protocol's own segments
    default = run_sim(tmp_path, SHORT_CYCLE, name="default.h5")
    as_run = yaml.safe_load(load_run(default.path).rig_config_text)
    assert as_run["sim"]["specimen"]["segments"] == ["B48-T30"]


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
    path.write_text(
        PARTIAL.format(segments=DEMO_SEGMENTS).replace("rig: sim", "rig: rigs/sim.yaml")
    )
    with pytest.raises(InputError, match=rf"sim\.yaml: line 4: sim\.specimen\.{key}: .*{allowed}"):
        load_rig_config(load_protocol(path))
