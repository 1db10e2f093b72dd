"""Bad input through the real entry point: one line and exit 2, never "internal error",
never a hang, for names, stored protocols and datasets no run of this rig could make."""

import os
import textwrap

import h5py
import pytest

from labrig.cli import main
from tests.support.simulated_runs import PROTOCOL, tiny_run

RUN = textwrap.dedent(
    """\
    name: {name}
    specimen: {{segments: [SI-B46-T20]}}
    limits: {{max_pressure_kpa: 95, max_volume_ml: 10}}
    steps: [{{infuse: {{rate_ml_min: 10, volume_ml: 5}}}}]
    """
)


def run(argv, capsys):
    with pytest.raises(SystemExit) as exited:
        main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return exited.value.code, out, err


@pytest.mark.parametrize(
    ("name", "expected"),
    [
        (
            '"a\\0b"',
            "line 1: name: character 2 is a control character (code 0); only printable text",
        ),
        ("n" * 5000, "line 1: name: String should have at most 200 characters"),
    ],
)
def test_a_bad_name_is_refused_before_the_run(tmp_path, capsys, name, expected):
    protocol = tmp_path / "p.yaml"
    protocol.write_text(RUN.format(name=name))
    code, _, err = run(["run", protocol, "--sim", "--out", tmp_path / "r.h5"], capsys)
    assert code == 2
    assert err == f"error: {protocol}: {expected}\n"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["p.yaml"]


def replace_protocol(path, text):
    with h5py.File(path, "r+") as f:
        source = f["entry/protocol"].attrs["source_file"]
        del f["entry/protocol"]
        f["entry"].create_dataset("protocol", data=text).attrs["source_file"] = source


def test_a_stored_protocol_naming_a_device_is_one_line(tmp_path, capsys):
    path = tiny_run(tmp_path / "run.h5")
    replace_protocol(path, PROTOCOL.replace("SI-B46-T20", "/dev/zero"))
    code, _, err = run(["compare", path, "--json"], capsys)
    assert (code, err) == (2, "error: /dev/zero: is a device or a pipe, not a regular file\n")


def test_a_dataset_of_two_billion_values_is_one_line(tmp_path, capsys):
    path = tiny_run(tmp_path / "run.h5")
    with h5py.File(path, "r+") as f:  # chunked and never written: a small file
        group = f["entry/repetitions/rep_01/pressure"]
        del group["value"]
        group.create_dataset("value", shape=(2_000_000_000,), chunks=(1 << 20,), dtype="f8")
    code, _, err = run(["show", path], capsys)
    assert code == 2
    assert err == (
        f"error: {path}: /entry/repetitions/rep_01/pressure/value holds 2000000000 values, "
        "more than the 250000000 of any run of this rig\n"
    )


@pytest.mark.parametrize("command", ["show", "recover"])
def test_a_pipe_named_as_a_run_file_is_one_line(tmp_path, capsys, command):
    pipe = tmp_path / "run.h5"
    os.mkfifo(pipe)
    code, _, err = run([command, pipe], capsys)
    assert (code, err) == (2, f"error: {pipe}: not a regular file (a folder, a device or a pipe)\n")


@pytest.mark.parametrize("command", [["show"], ["model", "curve"], ["compare"]])
def test_a_path_the_system_refuses_is_one_line(tmp_path, capsys, command):
    name = tmp_path / ("x" * 300 + ".h5")
    code, _, err = run([*command, name], capsys)
    assert code == 2
    (line,) = err.splitlines()
    assert line.startswith(f"error: {name}: ") and "File name too long" in line


@pytest.mark.parametrize(
    ("command", "expected"),
    [
        (["runs"], "not a regular file or a folder (a device or a pipe)"),
        (["watch"], "not a regular file (a folder, a device or a pipe)"),
    ],
)
def test_a_pipe_is_never_called_missing(tmp_path, capsys, command, expected):
    pipe = tmp_path / "run.h5"
    os.mkfifo(pipe)
    code, _, err = run([*command, pipe], capsys)
    assert (code, err) == (2, f"error: {pipe}: {expected}\n")
