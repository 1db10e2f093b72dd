"""Every duration, rate, speed and size has finite bounds the rig can honour, checked at
validation with one line naming the file, the line and the key."""

import textwrap

import pytest

from labrig.cli import main
from labrig.config.protocol import (
    MAX_PRESSURE_SAMPLES,
    MAX_RATE_ML_MIN,
    MIN_RATE_ML_MIN,
    parse_protocol,
    plan,
)
from labrig.drivers.phd_ultra_protocol import rate_limits_ml_min
from labrig.errors import InputError
from labrig.recording.run_reader import MAX_DATASET_VALUES

BASE = textwrap.dedent(
    """\
    name: bounds
    specimen: {segments: [B46-T20]}
    limits: {max_pressure_kpa: 95, max_volume_ml: 45}
    acquisition: {pressure_rate_hz: RATE, camera_fps: FPS}
    steps:
      - zero_pressure: {duration_s: 1}
      - STEP
    """
)


def protocol(step="infuse: {rate_ml_min: 10, volume_ml: 5}", rate="1000", fps="0"):
    return BASE.replace("STEP", step).replace("RATE", rate).replace("FPS", fps)


def refusal(text: str) -> str:
    with pytest.raises(InputError) as error:
        parse_protocol(text, "p.yaml")
    message = str(error.value)
    assert "\n" not in message and "Traceback" not in message
    return message


@pytest.mark.parametrize(
    ("text", "expected"),
    [
        (
            protocol("hold: {seconds: 1.0e+300}"),
            "p.yaml: line 7: steps[1].hold.seconds: Input should be less than or equal to 604800",
        ),
        (
            protocol("infuse: {rate_ml_min: 1.0e-300, volume_ml: 5}"),
            "p.yaml: line 7: steps[1].infuse.rate_ml_min: Input should be greater than or "
            "equal to 0.000000001",
        ),
        (
            protocol("infuse: {rate_ml_min: 1.0e+300, volume_ml: 5}"),
            "p.yaml: line 7: steps[1].infuse.rate_ml_min: Input should be less than or equal "
            "to 500",
        ),
        (
            protocol("infuse: {rate_ml_min: 10, volume_ml: 1.0e+300}"),
            "p.yaml: line 7: steps[1].infuse.volume_ml: Input should be less than or equal to 140",
        ),
        (
            protocol().replace("max_volume_ml: 45", "max_volume_ml: 1.0e+300"),
            "p.yaml: line 3: limits.max_volume_ml: Input should be less than or equal to 140",
        ),
        (
            protocol(fps="0.01"),
            "p.yaml: line 4: acquisition.camera_fps: 0.01 frames per second is too few: a "
            "camera's first frame must come within 3 s of its start; 0 (no camera) or 1 to 60",
        ),
        (
            protocol(rate="0.001"),
            "p.yaml: line 4: acquisition.pressure_rate_hz: Input should be greater than or "
            "equal to 10",
        ),
    ],
)
def test_a_value_no_rig_honours_is_refused_with_its_key(text, expected):
    assert refusal(text) == expected


def test_48_khz_for_90_minutes_is_refused_at_validation():
    """260 million samples, which the readers refuse as more than 250 million."""
    message = refusal(protocol("hold: {seconds: 5400}", rate="48000"))
    assert message == (
        "p.yaml: line 1: (top level): the run takes 1.5 h at acquisition.pressure_rate_hz "
        "48000: 2.59e+08 pressure samples, more than the 225,000,000 a run file is read back "
        "with; at 48000 Hz a run lasts at most 1.302 h"
    )
    # 78 minutes fit, as a week at 10 Hz does
    parse_protocol(protocol("hold: {seconds: 4680}", rate="48000"))
    parse_protocol(protocol("hold: {seconds: 604800}", rate="10"))


def test_the_slowest_rate_of_the_pump_is_bounded_by_the_samples_it_records():
    message = refusal(protocol("infuse: {rate_ml_min: 1.0e-9, volume_ml: 5}", rate="10"))
    assert "pressure samples, more than the 225,000,000" in message


def test_the_samples_a_run_validates_with_are_fewer_than_a_reader_reads():
    """A tenth of the reader's bound is left for what a run adds to its plan."""
    assert MAX_PRESSURE_SAMPLES <= 0.9 * MAX_DATASET_VALUES


def test_the_rate_bounds_hold_every_syringe_a_rig_file_takes():
    """pump.syringe.diameter_mm is above 0.1 and at most 50 mm."""
    low, _ = rate_limits_ml_min(0.1)
    _, high = rate_limits_ml_min(50.0)
    assert low >= MIN_RATE_ML_MIN and high <= MAX_RATE_ML_MIN
    assert high > 0.8 * MAX_RATE_ML_MIN and low > 0.1 * MIN_RATE_ML_MIN


def test_more_than_1000_repetitions_are_refused():
    many = "repeat: {times: 1000, steps: [hold: {seconds: 1}]}\n  - hold: {seconds: 1}"
    assert refusal(protocol(many)) == (
        "p.yaml: line 1: (top level): the steps make 1001 repetitions, more than 1000: the "
        "run file lays out each before the first sample"
    )
    assert plan(parse_protocol(protocol(many.split("\n")[0]))).repetitions == 1000


@pytest.mark.parametrize(
    ("option", "value", "allowed"),
    [
        ("--speed", "1e-300", "0.5<=x<=1000000.0"),
        ("--speed", "0.01", "0.5<=x<=1000000.0"),
        ("--speed", "1e300", "0.5<=x<=1000000.0"),
        ("--live-hold", "1e300", "0.0<=x<=3600.0"),
    ],
)
def test_run_options_are_bounded(tmp_path, capsys, option, value, allowed):
    path = tmp_path / "p.yaml"
    path.write_text(protocol())
    with pytest.raises(SystemExit) as exited:
        main(["run", str(path), "--dry-run", option, value])
    _, err = capsys.readouterr()
    assert exited.value.code == 2
    assert f"Invalid value for '{option}': {float(value):g} is not in the range {allowed}." in err


def test_the_slowest_speed_is_accepted(tmp_path, capsys):
    path = tmp_path / "p.yaml"
    path.write_text(protocol())
    with pytest.raises(SystemExit) as exited:
        main(["run", str(path), "--dry-run", "--speed", "0.5"])
    assert exited.value.code in (0, None)
