"""Protocol validation: every bad input gets one precise message naming file, key path
and line; nothing in a protocol is ever evaluated."""

import json
import textwrap

import pytest

from labrig.config.protocol import InfuseStep, iter_steps, load_protocol, parse_protocol
from labrig.errors import InputError

GOOD = textwrap.dedent(
    """\
    name: combined actuator
    specimen: {segments: [SI-B46-T20, SI-B46-T22]}
    rig: sim
    limits: {max_pressure_kpa: 95, max_volume_ml: 50}
    acquisition: {pressure_rate_hz: 1000, camera_fps: 2}
    steps:
      - zero_pressure: {}
      - repeat:
          times: 5
          steps:
            - infuse: {rate_ml_min: 20, volume_ml: 45}
            - hold: {seconds: 5}
            - withdraw: {rate_ml_min: 20, volume_ml: 45}
    analysis: {average_last: 4, compare_model: true}
    """
)


def test_the_issue_example_is_valid_and_unrolls():
    protocol = parse_protocol(GOOD)
    leaves = list(iter_steps(protocol.steps))
    assert len(leaves) == 1 + 5 * 3
    infusions = [step for _, step in leaves if isinstance(step, InfuseStep)]
    assert [s.infuse.volume_ml for s in infusions] == [45.0] * 5
    assert leaves[1][0] == "steps[1].repeat(#1).steps[0]"
    assert protocol.acquisition.camera_fps == 2
    assert protocol.analysis.average_last == 4


def test_defaults_fill_optional_sections():
    text = GOOD.replace("acquisition: {pressure_rate_hz: 1000, camera_fps: 2}\n", "")
    text = text.replace("analysis: {average_last: 4, compare_model: true}\n", "")
    protocol = parse_protocol(text)
    assert protocol.acquisition.pressure_rate_hz == 1000
    assert protocol.acquisition.camera_fps == 0
    assert protocol.analysis.average_last == 4


@pytest.mark.parametrize(
    ("old", "new", "expected"),
    [
        (
            "rate_ml_min: 20, volume_ml: 45}\n        - hold",
            "rate_ml_min: -20, volume_ml: 45}\n        - hold",
            "line 11: steps[1].repeat.steps[0].infuse.rate_ml_min: Input should be greater than or "
            "equal to 0.000000001",
        ),
        (
            "seconds: 5",
            "seconds: five",
            "line 12: steps[1].repeat.steps[1].hold.seconds: Input should be a valid number",
        ),
        (
            "camera_fps: 2",
            "camera_fps: 2, exposure: 3",
            "line 5: acquisition.exposure: unknown key",
        ),
        (
            "- hold: {seconds: 5}",
            "- wait: {seconds: 5}",
            "line 12: steps[1].repeat.steps[1]: a step is a mapping with exactly one key",
        ),
        (
            "max_volume_ml: 50",
            "max_volume_ml: 40",
            "steps[1].repeat(#1).steps[0] brings the specimen to 45 mL, above "
            "limits.max_volume_ml = 40 mL",
        ),
        (
            "withdraw: {rate_ml_min: 20, volume_ml: 45}",
            "withdraw: {rate_ml_min: 20, volume_ml: 46}",
            "withdraws more than was infused",
        ),
        ("times: 5", "times: 0", "line 9: steps[1].repeat.times: Input should be greater"),
        ("times: 5", "times: '5'", "steps[1].repeat.times: Input should be a valid integer"),
        ("max_pressure_kpa: 95", "max_pressure_kpa: 250", "limits.max_pressure_kpa"),
        ("segments: [SI-B46-T20, SI-B46-T22]", "segments: []", "specimen.segments"),
        ("name: combined actuator\n", "", "line 1: name: required key is missing"),
    ],
)
def test_bad_protocols_are_rejected_with_file_key_and_line(old, new, expected):
    assert old in GOOD
    with pytest.raises(InputError) as error:
        parse_protocol(GOOD.replace(old, new, 1), "protocols/x.yaml")
    message = str(error.value)
    assert message.startswith("protocols/x.yaml: ")
    assert expected in message


def test_nested_repeat_is_rejected():
    text = GOOD.replace(
        "- hold: {seconds: 5}", "- repeat: {times: 2, steps: [{hold: {seconds: 1}}]}"
    )
    with pytest.raises(InputError, match="a repeat cannot contain another repeat"):
        parse_protocol(text)


def test_yaml_syntax_error_names_the_line():
    with pytest.raises(InputError, match=r"p\.yaml: line 4: not valid YAML: .*starts on line 3"):
        parse_protocol("name: x\nsteps:\n  - [unclosed\n", "p.yaml")


def test_python_tags_are_never_evaluated(tmp_path):
    marker = tmp_path / "pwned"
    text = f"name: !!python/object/apply:os.system ['touch {marker}']\n"
    with pytest.raises(InputError, match="not valid YAML"):
        parse_protocol(text)
    assert not marker.exists()


def test_a_list_is_not_a_protocol():
    with pytest.raises(InputError, match="a protocol is a YAML mapping"):
        parse_protocol("- 1\n- 2\n", "list.yaml")


def test_missing_file(tmp_path):
    with pytest.raises(InputError, match="no such protocol file"):
        load_protocol(tmp_path / "absent.yaml")


def test_loaded_protocol_keeps_its_text(tmp_path):
    path = tmp_path / "p.yaml"
    path.write_text(GOOD)
    loaded = load_protocol(path)
    assert loaded.text == GOOD
    assert loaded.protocol.name == "combined actuator"


def test_every_protocol_in_the_repository_is_valid():
    from pathlib import Path

    for path in sorted(Path(__file__).parents[2].joinpath("protocols").glob("*.yaml")):
        load_protocol(path)


def test_plan_counts_duration_volume_and_repetitions():
    from labrig.config.protocol import plan

    summary = plan(parse_protocol(GOOD))
    # zero 2 s + 5 x (45 mL at 20 mL/min = 135 s, hold 5 s, withdraw 135 s)
    assert summary.duration_s == pytest.approx(2 + 5 * (135 + 5 + 135))
    assert summary.infused_ml == pytest.approx(225)
    assert summary.withdrawn_ml == pytest.approx(225)
    assert summary.max_volume_ml == pytest.approx(45)
    assert summary.repetitions == 5


def test_loose_top_level_steps_form_one_repetition():
    from labrig.config.protocol import iter_plan

    text = GOOD.replace(
        "  - repeat:",
        "  - infuse: {rate_ml_min: 60, volume_ml: 5}\n"
        "  - withdraw: {rate_ml_min: 60, volume_ml: 5}\n"
        "  - repeat:",
    )
    repetitions = [rep for _, _, rep in iter_plan(parse_protocol(text).steps)]
    assert repetitions == [0, 1, 1] + [2] * 3 + [3] * 3 + [4] * 3 + [5] * 3 + [6] * 3


def test_cli_validate_and_schema(tmp_path, capsys):
    from labrig.cli import main

    path = tmp_path / "p.yaml"
    path.write_text(GOOD)
    with pytest.raises(SystemExit) as exited:
        main(["protocol", "validate", str(path)])
    assert exited.value.code == 0
    out = capsys.readouterr().out
    assert "valid protocol 'combined actuator': 5 repetitions, 22.9 min, 225 mL infused" in out

    path.write_text(GOOD.replace("times: 5", "times: -1"))
    with pytest.raises(SystemExit) as exited:
        main(["protocol", "validate", str(path)])
    assert exited.value.code == 2
    err = capsys.readouterr().err
    assert err.startswith(f"error: {path}: line 9: steps[1].repeat.times")

    with pytest.raises(SystemExit) as exited:
        main(["protocol", "schema"])
    schema = json.loads(capsys.readouterr().out)
    assert set(schema["required"]) >= {"name", "specimen", "limits", "steps"}
    assert "max_pressure_kpa" in json.dumps(schema)
