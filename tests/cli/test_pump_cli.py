"""``labrig pump``: the technician's commands against the emulator, in process, and the
emulator command itself in a subprocess driven by the real driver and a second CLI."""

from __future__ import annotations

import subprocess
import sys
import threading
import time

import pytest
import serial
from support.pump_clients import FLOWCHEM_ELITE11, WAIT

from labrig import cli as cli_module
from labrig.cli import pump as pump_cli
from labrig.drivers.phd_ultra import PhdUltra
from labrig.drivers.phd_ultra_protocol import parse_reply
from labrig.rig.devices import PumpState
from labrig.sim.pump import PumpEmulator
from labrig.time.clock import ScaledClock


def run_main(argv, capsys):
    with pytest.raises(SystemExit) as exited:
        cli_module.main(argv)
    out, err = capsys.readouterr()
    return exited.value.code, out, err


def table(out: str) -> dict[str, str]:
    """``status`` output as {name: value}: names and values are split by 2+ spaces."""
    rows = {}
    for line in out.splitlines():
        name, _, value = line.partition("  ")
        rows[name.strip()] = value.strip()
    return rows


@pytest.fixture
def emulator():
    with PumpEmulator(ScaledClock(100.0)) as emu:
        yield emu


@pytest.fixture(autouse=True)
def fast_polls(monkeypatch):
    monkeypatch.setattr(pump_cli, "POLL_S", 0.05)


def test_infuse_to_a_volume_then_status(emulator, capsys):
    code, out, _ = run_main(
        ["pump", "--port", emulator.port, "infuse", "--rate-ml-min", "30", "--volume-ml", "0.5"],
        capsys,
    )
    assert code == 0
    assert out.strip() == "infuse: 30 mL/min until 0.5 mL"
    code, out, _ = run_main(["pump", "--port", emulator.port, "status"], capsys)
    assert code == 0
    rows = table(out)
    assert rows["state"] in ("infusing", "target reached")
    assert rows["infuse rate"] == "30 mL/min"
    assert rows["target"] == "0.5000 mL"
    assert rows["diameter"] == "26.7000 mm"
    assert rows["withdrawn"] == "0.0000 mL"
    assert 0.0 <= float(rows["infused"].split()[0]) <= 0.5


def test_infuse_wait_follows_the_run_to_its_target(emulator, capsys):
    code, out, _ = run_main(
        [
            "pump",
            "--port",
            emulator.port,
            "infuse",
            "--rate-ml-min",
            "30",
            "--volume-ml",
            "0.5",
            "--wait",
        ],
        capsys,
    )
    assert code == 0
    assert out.splitlines()[-1].split() == [
        "target",
        "reached",
        "infused",
        "0.5000",
        "mL",
        "withdrawn",
        "0.0000",
        "mL",
    ]
    assert emulator.state is PumpState.TARGET_REACHED


def test_withdraw_with_a_new_diameter_until_stopped(emulator, capsys):
    code, out, _ = run_main(
        [
            "pump",
            "--port",
            emulator.port,
            "withdraw",
            "--rate-ml-min",
            "2",
            "--diameter-mm",
            "14.57",
        ],
        capsys,
    )
    assert code == 0
    assert "withdraw: 2 mL/min until stopped" in out
    assert f"labrig pump --port {emulator.port} stop" in out
    assert emulator.state is PumpState.WITHDRAWING
    code, out, _ = run_main(["pump", "--port", emulator.port, "status"], capsys)
    assert table(out)["diameter"] == "14.5700 mm"
    code, out, _ = run_main(["pump", "--port", emulator.port, "stop"], capsys)
    assert code == 0
    assert out.startswith("stopped: infused 0.0000 mL, withdrawn ")
    assert emulator.state is PumpState.IDLE


def test_version(emulator, capsys):
    code, out, _ = run_main(["pump", "--port", emulator.port, "version"], capsys)
    assert code == 0
    assert out.splitlines()[0] == "PHD ULTRA 3.0.5"
    assert "Serial number" in out


def test_a_stall_while_waiting_exits_as_a_device_error(capsys):
    clock = ScaledClock(100.0)
    with PumpEmulator(clock, load_pressure_kpa=lambda t_s: 1e4) as emulator:
        code, _, err = run_main(
            ["pump", "--port", emulator.port, "infuse", "--rate-ml-min", "1", "--wait"], capsys
        )
    assert code == 3
    assert err.startswith("error: the pump stalled")


def test_bad_input_and_missing_devices_are_one_line_errors(emulator, capsys):
    code, _, err = run_main(["pump", "status"], capsys)
    assert (code, err.count("\n")) == (2, 1)
    assert "--port is required" in err
    code, _, err = run_main(
        ["pump", "--port", emulator.port, "infuse", "--rate-ml-min", "500"], capsys
    )
    assert (code, err.count("\n")) == (2, 1)
    assert "outside this syringe's limits" in err
    assert not any(line.startswith("irate 5") for line in emulator.received)
    code, _, err = run_main(["pump", "--port", "/dev/no-such-pump", "status"], capsys)
    assert (code, err.count("\n")) == (3, 1)
    assert err.startswith("error: cannot open /dev/no-such-pump")
    assert "Traceback" not in err


EMULATE_LEFT_BY_OTHER_SOFTWARE = [
    *(sys.executable, "-m", "labrig", "pump", "emulate", "--speed", "50"),
    *("--poll", "on", "--strict-address"),
]


def test_emulate_serves_the_driver_and_another_cli_process():
    emulate = subprocess.Popen(
        # as a pump left by other software: poll on, only the manual's address form
        EMULATE_LEFT_BY_OTHER_SOFTWARE,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    watchdog = threading.Timer(20.0, emulate.kill)
    watchdog.start()
    try:
        port = emulate.stdout.readline().strip()
        assert port.startswith("/dev/")
        with PhdUltra.open(port) as pump:
            pump.clear_volumes()
            pump.set_target_volume(1.0)
            pump.set_infuse_rate(30.0)  # 2 s of emulated time: 40 ms at x50
            pump.infuse()
        status = subprocess.run(
            [sys.executable, "-m", "labrig", "pump", "--port", port, "status"],
            capture_output=True,
            text=True,
            timeout=20,
        )
        assert status.returncode == 0, status.stderr
        rows = table(status.stdout)
        assert rows["state"] == "target reached"
        assert rows["infused"] == "1.0000 mL"
        assert rows["force limit"] == "100 %"
        emulate.terminate()
        _, err = emulate.communicate(timeout=10)
        assert emulate.returncode == 0
        assert "emulator stopped" in err
    finally:
        watchdog.cancel()
        if emulate.poll() is None:
            emulate.kill()


def test_flowchems_elite11_sequence_runs_against_labrig_pump_emulate():
    """flowchem's own byte sequence (initialise, set a rate, infuse, poll, stop) through
    the pseudo-terminal that ``labrig pump emulate`` prints, as flowchem would open it:
    every answer complete, no error text, the prompts it expects."""
    emulate = subprocess.Popen(
        [
            *(sys.executable, "-m", "labrig", "pump", "emulate", "--speed", "50"),
            *("--reply-style", "prefixed", "--strict-address"),
        ],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    watchdog = threading.Timer(20.0, emulate.kill)
    watchdog.start()
    try:
        port_name = emulate.stdout.readline().strip()
        with serial.Serial(port_name, 115200, timeout=0.1) as port:
            for sent, expected in FLOWCHEM_ELITE11:
                if sent == WAIT:
                    time.sleep(expected / 50)
                    continue
                port.reset_input_buffer()  # as flowchem does before each command
                port.write(sent)
                reply = read_reply(port, expect_payload=expected.count(b"\r") > 0)
                assert b"error" not in reply.lower(), (sent, reply)
                # the prompt flowchem reads (address 00, state) ends every reply
                assert reply[-3:] == expected[-3:], (sent, reply)
                if b"ivolume" not in sent and b"crate" not in sent:
                    assert reply == expected, sent
        emulate.terminate()
        assert emulate.wait(timeout=10) == 0
    finally:
        watchdog.cancel()
        if emulate.poll() is None:
            emulate.kill()


def read_reply(port, *, expect_payload: bool) -> bytes:
    """Bytes until the driver's parser finds a complete reply (2 s at most)."""
    raw = b""
    deadline = time.monotonic() + 2.0
    while time.monotonic() < deadline:
        raw += port.read(port.in_waiting or 1)
        if parse_reply(raw, expect_payload=expect_payload) is not None:
            return raw
    raise AssertionError(f"incomplete reply {raw!r}")


def test_status_and_infuse_on_a_pump_that_does_not_say_it_is_infuse_only(capsys):
    """Left in poll on, strict about addresses, infuse-only, its ``metrics`` without a
    Direction line: ``status`` and ``infuse`` work (the refused ``wvolume`` says it
    cannot withdraw), and ``withdraw`` is refused before anything is sent."""
    options = {"poll_mode": "on", "strict_address_form": "none", "infuse_only": True}
    with PumpEmulator(ScaledClock(100.0), metrics_direction=False, **options) as emulator:
        code, out, err = run_main(["pump", "--port", emulator.port, "status"], capsys)
        assert code == 0, err
        rows = table(out)
        assert rows["state"] == "idle"
        assert rows["withdraw rate"] == "none (infuse-only pump)"
        assert rows["withdrawn"] == "0.0000 mL"
        infuse = ["infuse", "--rate-ml-min", "30", "--volume-ml", "0.5"]
        code, out, err = run_main(["pump", "--port", emulator.port, *infuse], capsys)
        assert code == 0, err
        assert out.strip() == "infuse: 30 mL/min until 0.5 mL"
        code, _, err = run_main(
            ["pump", "--port", emulator.port, "withdraw", "--rate-ml-min", "1"], capsys
        )
        assert code == 3 and "infuse-only" in err and err.count("\n") == 1
        withdraw_commands = [line for line in emulator.received if line.startswith("w")]
        assert set(withdraw_commands) == {"wvolume"}  # the probes at each connect only


def test_the_methods_the_command_offers_are_the_emulators():
    from labrig.sim.pump_methods import METHODS

    assert set(pump_cli.METHOD_NAMES) == set(METHODS)


def emulate_process(*options: str) -> tuple[subprocess.Popen, str]:
    process = subprocess.Popen(
        [sys.executable, "-m", "labrig", "pump", "emulate", "--speed", "50", *options],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    return process, process.stdout.readline().strip()


def test_emulate_survives_an_invalid_byte_without_a_traceback():
    emulate, port = emulate_process()
    watchdog = threading.Timer(20.0, emulate.kill)
    watchdog.start()
    try:
        with serial.Serial(port, 115200, timeout=5.0) as line:
            line.write(b"\xff")  # alone, then ended by CR: one unknown command
            line.write(b"\r")
            assert line.read_until(b"\n:").endswith(b"Unknown command\r\n:")
            line.write(b"ver\r")
            assert line.read_until(b"\n:") == b"\nPHD ULTRA 3.0.5\r\n:"
        emulate.terminate()
        _, err = emulate.communicate(timeout=10)
        assert emulate.returncode == 0
        assert "Traceback" not in err and "Error" not in err
    finally:
        watchdog.cancel()
        if emulate.poll() is None:
            emulate.kill()


INFUSE_HALF_ML = ("infuse", "--rate-ml-min", "30", "--volume-ml", "0.5")


def test_a_manual_run_on_a_pump_found_infusing_stops_it_and_says_so():
    emulate, port = emulate_process("--poll", "on", "--strict-address")
    watchdog = threading.Timer(30.0, emulate.kill)
    watchdog.start()
    try:
        with PhdUltra.open(port) as pump:  # another program left it infusing
            pump.clear_volumes()
            pump.set_infuse_rate(6.0)
            pump.infuse()
        infuse = subprocess.run(
            [sys.executable, "-m", "labrig", "pump", "--port", port, *INFUSE_HALF_ML],
            capture_output=True,
            text=True,
            timeout=20,
        )
        assert infuse.returncode == 0, infuse.stderr
        [said] = [line for line in infuse.stderr.splitlines() if "labrig stopped it" in line]
        assert said.startswith("the pump was infusing at 6 mL/min (")
    finally:
        watchdog.cancel()
        emulate.kill()
        emulate.communicate(timeout=10)
