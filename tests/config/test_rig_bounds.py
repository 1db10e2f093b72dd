"""A rig file's durations, rates, speeds and sizes have finite bounds the rig honours:
beyond them one line with the file, the line and the key; within them the simulated rig
runs to the end, also at the stiffest plumbing and the longest prompt it accepts."""

import textwrap

import pytest
from support.simrig import run_sim

from labrig.cli.run import MAX_SPEED, MIN_SPEED
from labrig.config.protocol import load_protocol
from labrig.config.rig_file import PumpConfig, RigConfig, SimConfig, load_rig_config
from labrig.errors import InputError

PROTOCOL = textwrap.dedent(
    """\
    name: rig bounds
    specimen: {segments: [B46-T20]}
    rig: rig.yaml
    limits: {max_pressure_kpa: 95, max_volume_ml: 45}
    steps:
      - infuse: {rate_ml_min: 10, volume_ml: 1}
    """
)


def refusal(tmp_path, rig: str) -> str:
    (tmp_path / "rig.yaml").write_text(rig)
    (tmp_path / "p.yaml").write_text(PROTOCOL)
    with pytest.raises(InputError) as error:
        load_rig_config(load_protocol(tmp_path / "p.yaml"))
    message = str(error.value)
    assert "\n" not in message and "Traceback" not in message
    return message.removeprefix(f"{tmp_path / 'rig.yaml'}: ")


@pytest.mark.parametrize(
    ("setting", "expected"),
    [
        (
            "sim: {answer_s: 1.0e+300}",
            "line 2: sim.answer_s: Input should be less than or equal to 30",
        ),
        (
            "sim: {coupling_bore_mm: 1.0e-300}",
            "line 2: sim.coupling_bore_mm: Input should be greater than or equal to 0.1",
        ),
        (
            "sim: {coupling_length_mm: 1.0e-300}",
            "line 2: sim.coupling_length_mm: Input should be greater than or equal to 1",
        ),
        (
            "sim: {dead_volume_ml: 1.0e+300}",
            "line 2: sim.dead_volume_ml: Input should be less than or equal to 100",
        ),
        (
            "sim: {resistance_kpa_s_per_ml: 1.0e-300}",
            "line 2: sim.resistance_kpa_s_per_ml: Input should be greater than or equal to 0.001",
        ),
        (
            "sim: {speed: 1.0e-300}",
            "line 2: sim.speed: Input should be greater than or equal to 0.5",
        ),
        (
            "sim: {reply_timeout_s: 1.0e+300}",
            "line 2: sim.reply_timeout_s: Input should be less than or equal to 60",
        ),
        (
            "signal_timeout_s: 1.0e-300",
            "line 2: signal_timeout_s: Input should be greater than or equal to 0.2",
        ),
        (
            "camera: {mm_per_px: 0.1, width: 1000000000}",
            "line 2: camera.width: Input should be less than or equal to 8192",
        ),
        (
            "camera: {mm_per_px: 0.1, fps: 1.0e-300}",
            "line 2: camera.fps: Input should be greater than or equal to 1",
        ),
    ],
)
def test_a_setting_no_rig_honours_is_refused_with_its_key(tmp_path, setting, expected):
    assert refusal(tmp_path, f"pump: {{port: emulator}}\n{setting}\n") == expected


def test_the_rig_file_paces_as_the_command_line_does():
    speed = SimConfig.model_fields["speed"].metadata
    assert [m.ge for m in speed if hasattr(m, "ge")] == [MIN_SPEED]
    assert [m.le for m in speed if hasattr(m, "le")] == [MAX_SPEED]


STEP = textwrap.dedent(
    """\
    name: the stiffest plumbing
    specimen: {segments: [B44-T30, B48-T26], fittings_length_mm: 10, fluid: water}
    rig: sim
    limits: {max_pressure_kpa: 95, max_volume_ml: 45}
    acquisition: {pressure_rate_hz: 100}
    steps:
      - zero_pressure: {duration_s: 1}
      - infuse: {rate_ml_min: 120, volume_ml: 18.7}
      - prompt: {message: open the reservoir, connect: reservoir}
      - reservoir: {volume_ml: 1.0, duration_s: 0.5}
      - hold: {seconds: 2}
    """
)


def test_the_stiffest_plumbing_and_the_longest_prompt_finish(tmp_path):
    """The widest, shortest coupling into the least dead volume is the stiffest system
    the step experiments' plant integrates, and half a minute's prompt the longest
    stretch it integrates at rest."""
    sim = SimConfig(answer_s=30, coupling_bore_mm=5, coupling_length_mm=1, dead_volume_ml=0.01)
    outcome = run_sim(tmp_path, STEP, config=RigConfig(pump=PumpConfig(port="emulator"), sim=sim))
    assert outcome.result.status == "complete", outcome.result.reason


def test_the_smallest_resistance_finishes(tmp_path):
    sim = SimConfig(resistance_kpa_s_per_ml=1e-3)
    text = STEP.split("  - prompt")[0].replace("the stiffest plumbing", "low resistance")
    outcome = run_sim(tmp_path, text, config=RigConfig(pump=PumpConfig(port="emulator"), sim=sim))
    assert outcome.result.status == "complete", outcome.result.reason
