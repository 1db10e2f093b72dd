"""The CLI's frame: version, help, lazy sub-commands, and errors as one clear line."""

import subprocess
import sys

import click
import pytest

import labrig
from labrig import cli as cli_module
from labrig.errors import InputError


def run_main(argv, capsys):
    with pytest.raises(SystemExit) as exited:
        cli_module.main(argv)
    out, err = capsys.readouterr()
    return exited.value.code, out, err


def test_version(capsys):
    code, out, _ = run_main(["--version"], capsys)
    assert code == 0
    assert out.strip() == f"labrig, version {labrig.__version__}"


def test_help_lists_only_registered_commands(capsys):
    code, out, _ = run_main(["--help"], capsys)
    assert code == 0
    assert "Usage: labrig" in out
    for name in cli_module.COMMANDS:
        assert name in out


def test_unknown_command_is_a_usage_error(capsys):
    code, _, err = run_main(["no-such-command"], capsys)
    assert code == 2
    assert "No such command" in err


def test_labrig_errors_become_one_line_with_their_exit_code(capsys, monkeypatch):
    @click.command()
    def broken():
        raise InputError("protocols/x.yaml: steps[0].infuse.rate_ml_min: must be > 0")

    module = type(sys)("fake_cli_module")
    module.broken = broken
    monkeypatch.setitem(sys.modules, "fake_cli_module", module)
    monkeypatch.setitem(cli_module.COMMANDS, "broken", ("fake_cli_module", "broken"))
    code, _, err = run_main(["broken"], capsys)
    assert code == 2
    assert err.strip() == "error: protocols/x.yaml: steps[0].infuse.rate_ml_min: must be > 0"
    assert "Traceback" not in err


def test_help_imports_no_heavy_module():
    code = (
        "import sys\n"
        "from labrig.cli import main\n"
        "try:\n    main(['--help'])\nexcept SystemExit:\n    pass\n"
        "names = ('cv2', 'matplotlib', 'nidaqmx', 'scipy', 'h5py', 'numba')\n"
        "heavy = [m for m in names if m in sys.modules]\n"
        "print('HEAVY=' + ','.join(heavy))\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip().splitlines()[-1] == "HEAVY="


@pytest.mark.parametrize(
    ("args", "one_actuator"),
    [
        (["run", "protocols/demo.yaml", "--sim"], True),
        (["run", "protocols/demo.yaml", "--dry-run"], True),
        (["compare", "runs/RUN.h5", "--json"], True),
        (["model", "path", "SI-B48-T30", "SI-B50-T20"], True),
        (["library", "add", "runs/RUN.h5", "--name", "S"], True),
        (["model", "scan", "--n", "3"], False),
        (["--debug", "model", "scan", "--n", "3"], False),
        (["bench", "model", "--scans", "2"], False),
    ],
)
def test_only_the_commands_that_solve_many_actuators_compile(args, one_actuator):
    """Which mode the console script picks (tests/model/actuator/test_jit.py checks, in a
    subprocess, that a plain-Python command imports no numba)."""
    assert cli_module._solves_one_actuator(args) is one_actuator


def test_namespaced_packages_map_to_the_top_level_folders():
    import labrig.drivers
    import labrig.sim

    assert labrig.drivers.__file__.replace("\\", "/").endswith("drivers/__init__.py")
    assert labrig.sim.__file__.replace("\\", "/").endswith("sim/__init__.py")


def test_console_script_runs():
    out = subprocess.run(
        [sys.executable, "-m", "labrig", "--version"], capture_output=True, text=True, check=True
    )
    assert labrig.__version__ in out.stdout
