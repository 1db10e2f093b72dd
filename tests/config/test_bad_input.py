"""Bad input, whole: every malformed or hostile protocol, rig file or path is one clear
line, at once, with nothing of a named file's content in it."""

import os
import textwrap
import time

import pytest

from labrig.config.protocol import load_protocol, parse_protocol
from labrig.config.rig_file import load_rig_config
from labrig.errors import InputError
from labrig.model.segments.catalog import load_segment

BASE = textwrap.dedent(
    """\
    name: bad input
    specimen: {segments: [SI-B46-T20]}
    rig: sim
    limits: {max_pressure_kpa: 95, max_volume_ml: 45}
    steps:
      - infuse: {rate_ml_min: 20, volume_ml: 10}
      - hold: {seconds: 5}
    """
)


def refused(text: str) -> str:
    """The one-line error of parsing ``text``, which must come at once."""
    started = time.process_time()
    with pytest.raises(InputError) as error:
        parse_protocol(text, "p.yaml")
    # CPU time, not wall time: a bound on the work, whatever the machine's load
    assert time.process_time() - started < 5.0
    return str(error.value)


@pytest.mark.parametrize(
    ("old", "new", "expected"),
    [
        ("seconds: 5", "seconds: .inf", "line 7: steps[1].hold.seconds: Input should be a finite"),
        ("max_volume_ml: 45", "max_volume_ml: .inf", "limits.max_volume_ml: Input should be a fin"),
        ("max_volume_ml: 45", "max_volume_ml: .nan", "limits.max_volume_ml: Input should be a fin"),
        ("rate_ml_min: 20", "rate_ml_min: .NaN", "steps[0].infuse.rate_ml_min: Input should be"),
    ],
)
def test_infinite_and_nan_numbers_are_refused(old, new, expected):
    assert expected in refused(BASE.replace(old, new))


def test_a_key_given_twice_is_refused_naming_both_lines():
    text = BASE.replace(
        "limits: {max_pressure_kpa: 95, max_volume_ml: 45}",
        "limits:\n  max_pressure_kpa: 95\n  max_volume_ml: 45\n  max_pressure_kpa: 20",
    )
    assert refused(text) == (
        "p.yaml: line 7: not valid YAML: key 'max_pressure_kpa' given twice in one mapping "
        "(line 5 and line 7); keep one"
    )
    flow = BASE.replace("{seconds: 5}", "{seconds: 5, seconds: 6}")
    assert "key 'seconds' given twice in one mapping (line 7 and line 7)" in refused(flow)


def test_anchors_and_merge_keys_still_work():
    merged = "{<<: *flow, volume_ml: 5}"
    text = BASE.replace(
        "steps:\n  - infuse: {rate_ml_min: 20, volume_ml: 10}",
        f"base: &flow {{rate_ml_min: 20, volume_ml: 10}}\nsteps:\n  - infuse: {merged}",
    )
    # `base` is no protocol key: refused as unknown, and the merge is no duplicate
    assert refused(text).startswith("p.yaml: line 5: base: unknown key")
    steps = "  - infuse: &flow {rate_ml_min: 20, volume_ml: 10}\n  - withdraw: *flow\n"
    protocol = parse_protocol(BASE.split("steps:")[0] + "steps:\n" + steps)
    assert protocol.steps[1].withdraw.volume_ml == 10


def test_an_alias_flood_is_refused_at_once():
    flood = "x: &x [1]\nname: [" + ", ".join(["*x"] * 100_000) + "]\n"
    assert "line 2: not valid YAML: more than 1000 aliases" in refused(flood)


def test_aliases_that_expand_to_billions_are_refused_at_once():
    lines = ["a0: &a0 [B46-T20, B46-T20, B46-T20, B46-T20, B46-T20, B46-T20, B46-T20]"]
    lines += [f"a{i}: &a{i} [" + ", ".join([f"*a{i - 1}"] * 7) + "]" for i in range(1, 10)]
    text = "\n".join(lines) + "\n" + BASE.replace("segments: [SI-B46-T20]", "segments: *a9")
    assert "expands through its aliases to more than 100000 values" in refused(text)
    assert "an alias inside its own anchor" in refused("name: &n [1, *n]\n")


def test_deep_nesting_is_refused_at_once():
    text = "name: " + "[" * 20_000 + "]" * 20_000 + "\n"
    assert refused(text) == "p.yaml: line 1: not valid YAML: nested more than 64 levels deep"


@pytest.mark.parametrize(
    ("name", "expected"),
    [
        ('"run\\0one"', "name: character 4 is a control character (code 0)"),
        ("x" * 5000, "name: String should have at most 200 characters"),
        ('"two\\nlines"', "name: character 4 is a control character (code 10)"),
    ],
)
def test_names_are_checked_before_the_run(name, expected):
    assert expected in refused(BASE.replace("name: bad input", f"name: {name}"))


def test_a_nul_in_a_segment_path_is_refused():
    text = BASE.replace("[SI-B46-T20]", '["a\\0b.csv"]')
    assert "specimen.segments[0]: character 2 is a control character" in refused(text)


@pytest.fixture
def fifo(tmp_path):
    path = tmp_path / "pipe.csv"
    os.mkfifo(path)
    return path


@pytest.mark.parametrize("special", ["/dev/zero", "fifo", "folder"])
def test_only_regular_files_are_read(tmp_path, fifo, special):
    path = {"/dev/zero": "/dev/zero", "fifo": str(fifo), "folder": str(tmp_path)}[special]
    kind = "a folder" if special == "folder" else "a device or a pipe"
    with pytest.raises(InputError, match=f"^{path}: is {kind}, not a regular file$"):
        load_protocol(path)
    with pytest.raises(InputError, match=f"{path}: is {kind}, not a regular file$"):
        load_segment(path)
    protocol = tmp_path / "p.yaml"
    protocol.write_text(BASE.replace("rig: sim", f"rig: {path}"))
    with pytest.raises(InputError, match=f"rig: cannot read rig file {path}: is {kind}"):
        load_rig_config(load_protocol(protocol))


def test_no_content_of_a_named_file_is_echoed(tmp_path):
    secret = tmp_path / "shadow"
    secret.write_text("root:$6$saltsalt$hashhashhash:19000:0:99999:7:::\n")
    with pytest.raises(InputError) as error:
        load_segment(str(secret))
    assert str(error.value) == (
        f"{secret}: line 1: the header must be volume_ml,pressure_kpa,length_mm"
    )
    rig = tmp_path / "p.yaml"
    rig.write_text(BASE.replace("rig: sim", f"rig: {secret}"))
    with pytest.raises(InputError) as error:
        load_rig_config(load_protocol(rig))
    assert "(a key that is no name): unknown key" in str(error.value)
    assert "saltsalt" not in str(error.value) and "19000" not in str(error.value)


def test_a_huge_number_in_a_curve_is_one_line(tmp_path):
    rows = ["volume_ml,pressure_kpa,length_mm"]
    rows += [f"{v},{5.0 * v},{30.0 + v}" for v in range(12)]
    rows[6] = "5,1e308,35"
    table = tmp_path / "huge.csv"
    table.write_text("\n".join(rows) + "\n")
    with pytest.raises(InputError) as error:
        load_segment(str(table))
    assert str(error.value) == (
        f"{table}: line 7, column pressure_kpa: beyond +-1e+06 (mL, kPa, mm): not a segment's curve"
    )


@pytest.mark.parametrize(
    ("rig", "expected"),
    [
        ('pump: {port: "/dev/ttyACM0\\0"}', "line 1: pump.port: character 13 is a control"),
        (
            'pump: {port: x}\ncamera: {source: "cam\\0", mm_per_px: 0.1}',
            "line 2: camera.source: character 4 is a control",
        ),
        ("pump: {port: x}\nsignal_timeout_s: .nan", "signal_timeout_s: Input should be a finite"),
    ],
)
def test_a_rig_file_names_its_devices_in_printable_text(tmp_path, rig, expected):
    (tmp_path / "rig.yaml").write_text(rig)
    protocol = tmp_path / "p.yaml"
    protocol.write_text(BASE.replace("rig: sim", "rig: rig.yaml"))
    with pytest.raises(InputError, match=expected):
        load_rig_config(load_protocol(protocol))
