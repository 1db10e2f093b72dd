"""The PHD ULTRA emulator on its own: the plunger's volumes against hand calculations,
and its serial framing byte for byte over a real pseudo-terminal (plain pyserial, no
driver)."""

from __future__ import annotations

import logging
import math
import time

import pytest
import serial
from hypothesis import given, settings
from hypothesis import strategies as st

from labrig.drivers.phd_ultra_protocol import parse_rate_limits
from labrig.rig.devices import PumpState
from labrig.sim.pump import LOG_LIMIT, PumpEmulator
from labrig.sim.syringe_drive import INFUSE, WITHDRAW, SyringeDrive
from labrig.time.virtual import VirtualClock

# ---- the plunger, as a function of time ---------------------------------------------


def test_net_volume_is_piecewise_linear_through_every_event():
    drive = SyringeDrive(0.0)
    drive.start(INFUSE, 6.0, 0.0)  # 0.1 mL/s
    drive.change_rate(12.0, 10.0)  # 0.2 mL/s
    drive.halt(20.0)
    drive.start(WITHDRAW, 6.0, 30.0)
    drive.halt(40.0)
    # By hand: +1.0 mL in 0-10 s, +2.0 mL in 10-20 s, -1.0 mL in 30-40 s.
    expected = {0: 0.0, 5: 0.5, 10: 1.0, 15: 2.0, 20: 3.0, 25: 3.0, 35: 2.5, 40: 2.0, 90: 2.0}
    for t_s, net_ml in expected.items():
        assert drive.net_ml(t_s) == pytest.approx(net_ml, abs=1e-12), t_s
    assert drive.counted_ml(INFUSE, 90.0) == pytest.approx(3.0)
    assert drive.counted_ml(WITHDRAW, 90.0) == pytest.approx(1.0)
    assert drive.run_time_s(INFUSE, 90.0) == pytest.approx(20.0)
    assert drive.run_time_s(WITHDRAW, 90.0) == pytest.approx(10.0)


def test_the_target_stops_the_plunger_exactly_however_late_it_is_noticed():
    drive = SyringeDrive(0.0)
    drive.set_target(1.5, 0.0)
    drive.start(INFUSE, 6.0, 0.0)
    assert drive.end_s() == pytest.approx(15.0)
    assert not drive.settle(14.9)
    # Read before anyone settles it, the volume already stops at the target.
    assert drive.counted_ml(INFUSE, 40.0) == pytest.approx(1.5, abs=1e-12)
    assert drive.settle(40.0)
    assert (drive.running, drive.target_reached, drive.t0_s) == (False, True, pytest.approx(15.0))
    assert drive.net_ml(100.0) == pytest.approx(1.5, abs=1e-12)
    # Running again with the target met ends at once.
    drive.start(INFUSE, 6.0, 50.0)
    assert drive.target_reached
    assert not drive.running


def test_a_target_below_the_volume_moved_stops_now_and_never_goes_back():
    drive = SyringeDrive(0.0)
    drive.start(INFUSE, 6.0, 0.0)
    drive.set_target(0.5, 10.0)  # 1.0 mL moved already
    assert drive.settle(10.0)
    assert drive.counted_ml(INFUSE, 20.0) == pytest.approx(1.0)


def test_clearing_the_counters_leaves_the_physical_volume():
    drive = SyringeDrive(0.0, net_ml=0.25)
    drive.start(INFUSE, 6.0, 0.0)
    drive.clear(INFUSE, 10.0)
    assert drive.counted_ml(INFUSE, 20.0) == pytest.approx(1.0)
    assert drive.net_ml(20.0) == pytest.approx(0.25 + 2.0)


# ---- over the pseudo-terminal ---------------------------------------------------------

QUIET_S = 0.03  # once a reply has started, this long without bytes ends it
FIRST_BYTE_S = 2.0  # generous: a loaded host may be slow to schedule the emulator


def exchange(port: serial.Serial, sent: bytes) -> bytes:
    """Send bytes and collect the reply until the line stays quiet for QUIET_S."""
    port.write(sent)
    deadline = time.monotonic() + FIRST_BYTE_S
    received = b""
    while not received and time.monotonic() < deadline:
        received = port.read(4096)
    while chunk := port.read(4096):
        received += chunk
    return received


def silence(port: serial.Serial, sent: bytes, wait_s: float = 0.2) -> bytes:
    """Send bytes to which no reply is expected; return whatever came within ``wait_s``."""
    port.write(sent)
    time.sleep(wait_s)
    return port.read(port.in_waiting)


@pytest.fixture
def clock():
    return VirtualClock()


@pytest.fixture
def emulator(clock):
    with PumpEmulator(clock) as emu:
        yield emu


@pytest.fixture
def port(emulator):
    with serial.Serial(emulator.port, 115200, timeout=QUIET_S) as opened:
        yield opened


def test_replies_follow_the_pump_framing_at_address_0(port):
    table = [
        (b"ver\r", b"\nPHD ULTRA 3.0.5\r\n:"),
        (b"00ver\r", b"\nPHD ULTRA 3.0.5\r\n:"),
        (b"0:ver\r", b"\nPHD ULTRA 3.0.5\r\n:"),
        (b"\r", b"\n:"),
        (b"diam\r", b"\n26.7000 mm\r\n:"),
        (b"irate 6 ml/min\r\n", b"\n:"),  # CR LF ends one command, not two
        (b"irat\r", b"\n6 ml/min\r\n:"),
        (b"00wrate 90 ul/hr\n", b"\n:"),
        (b"wrate\r", b"\n90 ul/hr\r\n:"),
        (b"ivolume\r", b"\n0 ul\r\n:"),
        (b"tvolume\r", b"\nTarget volume not set\r\n:"),
        (b"tvol 2 ml\r", b"\n:"),
        (b"tvolume\r", b"\n2 ml\r\n:"),
        (b"force\r", b"\n100%\r\n:"),
        (b"status\r", b"\n0 0 0 i..TI.\r\n:"),
        (b"bogus\r", b"\nCommand error: [bogus]\r\n   Unknown command\r\n:"),
        (
            b"irate 500 ml/min\r",
            b"\nRange error: 500\r\n   Rate out of range of 116.13 nl/min to 120.597 ml/min.\r\n:",
        ),
        (
            b"irate 5 furlongs/min\r",
            b"\nArgument error: [furlongs/min]\r\n   Unknown argument\r\n:",
        ),
        (b"svolume 10 nl\r", b"\nArgument error: [10 nl]\r\n   Unknown argument\r\n:"),
    ]
    for sent, received in table:
        assert exchange(port, sent) == received, sent
    assert silence(port, b"05ver\r") == b""  # another pump's address


def test_a_nonzero_address_in_both_forms_and_the_prefixed_reply_style(clock):
    with (
        PumpEmulator(clock, address=12, reply_style="prefixed") as emu,
        serial.Serial(emu.port, 115200, timeout=QUIET_S) as port,
    ):
        assert exchange(port, b"12:ver\r") == b"\n12:PHD ULTRA 3.0.5\r\n12:"
        assert exchange(port, b"12ver\r") == b"\n12:PHD ULTRA 3.0.5\r\n12:"
        assert exchange(port, b"12irun\r") == b"\n12>"
        assert exchange(port, b"12:stp\r") == b"\n12:"
        assert silence(port, b"0:ver\r") == b""


def test_the_status_line_while_running_counts_femtolitres(port, clock):
    exchange(port, b"irate 6 ml/min\r")
    start_s = clock.now()
    exchange(port, b"irun\r")
    clock.sleep(5.0)
    reply = exchange(port, b"status\r")
    end_s = clock.now()
    fields = reply.decode().strip().split()
    assert reply.endswith(b"\r\n>")
    # 6 mL/min = 0.1 mL/s = 1e11 fL/s; the volume is 1e11 fL per second of running.
    assert int(fields[0]) == 100_000_000_000
    volume_fl, time_s = int(fields[2]), int(fields[1])
    assert 5.0e11 <= volume_fl <= 1e11 * (end_s - start_s)
    # The time field counts whole seconds of running (the manual: "in seconds").
    assert time_s == math.floor(volume_fl / 1e11)
    assert fields[3] == "I..TI."


def test_the_target_ends_the_run_with_an_unsolicited_prompt():
    clock = VirtualClock()  # slow enough that irun's own exchange ends first
    with (
        PumpEmulator(clock) as emulator,
        serial.Serial(emulator.port, 115200, timeout=QUIET_S) as port,
    ):
        exchange(port, b"irate 30 ml/min\r")  # 0.5 mL/s
        exchange(port, b"tvolume 1 ml\r")
        assert exchange(port, b"irun\r") == b"\n>"
        clock.sleep(2.5)  # the target is reached after 2 s
        # Nothing sent: the pump announces it by itself.
        assert port.read(16) == b"\nT*"
        assert exchange(port, b"ivolume\r") == b"\n1 ml\r\nT*"
        assert exchange(port, b"status\r") == b"\n0 2 1000000000000 i..TIT\r\nT*"
        assert emulator.state is PumpState.TARGET_REACHED
        assert exchange(port, b"stop\r") == b"\n:"
        assert emulator.net_volume_ml(clock.now()) == pytest.approx(1.0, abs=1e-12)


def test_older_firmware_sends_the_status_line_after_the_prompt(clock):
    with (
        PumpEmulator(clock, status_prompt_first=True, target_prompt="T:") as emu,
        serial.Serial(emu.port, 115200, timeout=QUIET_S) as port,
    ):
        assert exchange(port, b"status\r") == b"\n:\n0 0 0 i..TI.\r\n"


def test_replies_written_in_pieces_arrive_whole(clock):
    with (
        PumpEmulator(clock, reply_chunk_bytes=2, chunk_gap_s=0.002) as emu,
        serial.Serial(emu.port, 115200, timeout=QUIET_S) as port,
    ):
        assert exchange(port, b"ver\r") == b"\nPHD ULTRA 3.0.5\r\n:"


def test_rate_limits_scale_with_the_plunger_area(port):
    full = parse_rate_limits(exchange(port, b"irate lim\r").decode().split("\r")[0].strip())
    exchange(port, b"diameter 13.35\r")
    half = parse_rate_limits(exchange(port, b"irate lim\r").decode().split("\r")[0].strip())
    assert full[0] / half[0] == pytest.approx(4.0, rel=1e-4)
    assert full[1] / half[1] == pytest.approx(4.0, rel=1e-4)
    # A set rate beyond the new syringe's range is brought inside it.
    exchange(port, b"irate max\r")
    assert exchange(port, b"irate\r") == b"\n" + f"{half[1]:.4f} ml/min".encode() + b"\r\n:"


def test_the_stall_limit_is_the_force_over_the_plunger_area(clock):
    # 75 lbf on a 26.7 mm plunger: F / (pi d^2 / 4).
    limit_kpa = 75 * 4.4482216 / (math.pi * 0.0267**2 / 4) / 1e3
    loads = {"kpa": limit_kpa * 0.98}
    with (
        PumpEmulator(clock, load_pressure_kpa=lambda t_s: loads["kpa"]) as emu,
        serial.Serial(emu.port, 115200, timeout=QUIET_S) as port,
    ):
        assert emu.stall_pressure_kpa == pytest.approx(limit_kpa, rel=1e-9)
        assert exchange(port, b"irun\r") == b"\n>"
        clock.sleep(2.0)
        assert exchange(port, b"status\r").endswith(b"I..TI.\r\n>")
        loads["kpa"] = limit_kpa * 1.02
        assert exchange(port, b"status\r").endswith(b"i.STI.\r\n*")  # silently stalled
        assert exchange(port, b"stop\r") == b"\n:"
        # At half force the same load stalls at once.
        exchange(port, b"force 50\r")
        assert emu.stall_pressure_kpa == pytest.approx(limit_kpa / 2, rel=1e-9)
        loads["kpa"] = limit_kpa * 0.51
        exchange(port, b"irun\r")
        assert exchange(port, b"status\r").endswith(b"*")


def test_the_load_is_asked_at_non_decreasing_times(clock):
    times = []

    def load(t_s: float) -> float:
        times.append(t_s)
        return 0.0

    with (
        PumpEmulator(clock, load_pressure_kpa=load) as emu,
        serial.Serial(emu.port, 115200, timeout=QUIET_S) as port,
    ):
        exchange(port, b"irun\r")
        for _ in range(5):
            clock.sleep(0.5)  # checked every 0.1 s of clock time while it runs
            exchange(port, b"ivolume\r")
    assert len(times) > 25
    assert times == sorted(times)


def test_faults_at_the_serial_level(port, emulator):
    emulator.drop_next_replies(1)
    assert silence(port, b"ver\r") == b""
    assert exchange(port, b"ver\r") == b"\nPHD ULTRA 3.0.5\r\n:"
    emulator.inject_garbage(6)
    garbled = exchange(port, b"ver\r")
    assert garbled.endswith(b"\r\n:")
    assert any(byte >= 0x80 for byte in garbled)
    emulator.disconnect()
    with pytest.raises(serial.SerialException):
        port.write(b"ver\r")
        port.read(1)


# ---- models of real pumps ------------------------------------------------------------


def test_poll_modes_frame_the_replies_and_the_target_event():
    clock = VirtualClock()
    with (
        PumpEmulator(clock, poll_mode="on") as emulator,
        serial.Serial(emulator.port, 115200, timeout=QUIET_S) as port,
    ):
        assert exchange(port, b"ver\r") == b"\nPHD ULTRA 3.0.5\r\n:\x11"
        assert exchange(port, b"poll\r") == b"\nOn\r\n:\x11"
        exchange(port, b"irate 30 ml/min\r")
        exchange(port, b"tvolume 1 ml\r")
        assert exchange(port, b"irun\r") == b"\n>\x11"
        clock.sleep(2.5)
        assert silence(port, b"") == b""  # poll on: no event prompt at the target
        assert exchange(port, b"poll remote\r") == b"\nT*\x11"  # framed as it arrived
        assert exchange(port, b"ivolume\r") == b"\n1 ml\r"  # remote: no prompt
        assert silence(port, b"stop\r") == b""
        assert exchange(port, b"poll off\r") == b""
        assert exchange(port, b"poll\r") == b"\nOff\r\n:"


@pytest.mark.parametrize(
    ("address", "form", "answered", "ignored"),
    [
        (0, "none", b"ver\r", [b"00ver\r", b"0:ver\r"]),
        (12, "colon", b"12:ver\r", [b"12ver\r", b"ver\r", b"1:ver\r"]),
        (5, "digits", b"05ver\r", [b"5:ver\r", b"ver\r"]),
    ],
)
def test_strict_addressing_ignores_every_other_form(clock, address, form, answered, ignored):
    with (
        PumpEmulator(clock, address=address, strict_address_form=form) as emulator,
        serial.Serial(emulator.port, 115200, timeout=QUIET_S) as port,
    ):
        for sent in ignored:
            assert silence(port, sent) == b"", sent
        assert exchange(port, answered).startswith(b"\nPHD ULTRA 3.0.5\r\n")


def test_an_infuse_only_model_and_firmware_memory_commands(clock):
    unknown = b"\r\n   Unknown command\r\n:"
    with (
        PumpEmulator(clock, infuse_only=True, memory_command="rsave") as emulator,
        serial.Serial(emulator.port, 115200, timeout=QUIET_S) as port,
    ):
        for word in (b"wrate lim", b"wrun", b"wvolume", b"rrun", b"cwvolume"):
            name = emulator.firmware._aliases.get(word.decode(), word.decode()).split()[0]
            assert (
                exchange(port, word + b"\r")
                == b"\nCommand error: [" + name.encode() + b"]" + unknown
            )
        assert exchange(port, b"irate lim\r").endswith(b"ml/min\r\n:")
        assert exchange(port, b"nvram off\r") == b"\nCommand error: [nvram]" + unknown
        assert exchange(port, b"rsave off\r") == b"\n:"
        assert exchange(port, b"rsave\r") == b"\nOff\r\n:"
        assert exchange(port, b"rsave none\r").startswith(b"\nArgument error: [none]")


def test_the_by_id_link_is_gone_while_the_pump_is_and_follows_it_back(tmp_path):
    """As udev's: a link left at a released pseudo-terminal would lead a driver that
    reopens it into whatever terminal the OS hands that number to next (it did: a
    soak's driver set an operator's terminal to raw mode, Ctrl-C and all)."""
    link = tmp_path / "usb-Harvard_Apparatus_PHD_ULTRA-if00"
    emulator = PumpEmulator(VirtualClock(), by_id=link).start()
    try:
        first = emulator.tty_path
        assert str(link.resolve()) == first
        emulator.re_enumerate(0.2)
        assert not link.exists() and not link.is_symlink()
        deadline = time.monotonic() + 10.0
        while not link.exists() and time.monotonic() < deadline:
            time.sleep(0.01)
        assert emulator.tty_path != first
        assert str(link.resolve()) == emulator.tty_path
        with serial.Serial(str(link), timeout=2) as port:
            port.write(b"ver\r")
            assert port.read_until(b"PHD ULTRA").endswith(b"PHD ULTRA")
        emulator.disconnect()
        assert not link.is_symlink()
    finally:
        emulator.close()
    assert not link.is_symlink()


# ---- any byte, any amount: the emulator answers on and its log stays bounded ----------

# what the emulator may log, at most, of each kind of trouble: LOG_LIMIT records and the
# one saying the rest are counted
LOG_BOUND = 3 * (LOG_LIMIT + 1)


def _drain(port: serial.Serial) -> None:
    """Read until the line has been quiet for a while (replies to what was sent)."""
    while port.read(4096):
        pass


def _answers_ver(port: serial.Serial) -> bool:
    """Back to a known state (what random bytes may have set: poll mode, address),
    then the pump must answer ``ver`` as ever."""
    port.write(b"\rpoll off\raddress 0\r")
    _drain(port)
    port.write(b"ver\r")
    answer = b"\nPHD ULTRA 3.0.5\r\n:"
    port.timeout = 5.0  # a late reply to the noise may still come first on a busy host
    try:
        return port.read_until(answer).endswith(answer)
    finally:
        port.timeout = QUIET_S


@settings(max_examples=60, deadline=None)
@given(noise=st.binary(min_size=1, max_size=600))
def test_any_bytes_leave_the_emulator_answering(noise):
    """One ``\\xff`` once ended the serving thread (an error encoding its refusal) and
    took the pseudo-terminal with it while the process went on serving."""
    log = logging.getLogger("labrig.sim.pump")
    records = []
    handler = logging.Handler()
    handler.emit = records.append
    log.addHandler(handler)
    try:
        with (
            PumpEmulator(VirtualClock()) as emulator,
            serial.Serial(emulator.port, 115200, timeout=QUIET_S) as port,
        ):
            port.write(noise)
            _drain(port)
            assert _answers_ver(port)
            assert emulator.serving
            assert emulator.troubles["error"] == 0  # every line answered, none failed
    finally:
        log.removeHandler(handler)
    assert len(records) <= LOG_BOUND


def test_a_single_invalid_byte_is_answered_as_an_unknown_command(emulator, port):
    port.write(b"\xff\r")
    port.timeout = 5.0
    assert port.read_until(b"\n:") == b"\nCommand error: [?]\r\n   Unknown command\r\n:"
    assert emulator.serving


def test_a_flood_is_answered_with_a_bounded_log(emulator, caplog):
    """Megabytes of bad lines and one endless line, with nobody reading the replies:
    the output buffer fills, the long line is cut, and the log says so a few times."""
    with (
        caplog.at_level(logging.WARNING, logger="labrig.sim.pump"),
        serial.Serial(emulator.port, 115200, timeout=QUIET_S, write_timeout=30) as port,
    ):
        for _ in range(40):
            port.write(b"\xff\xfe\r" * 5000)
        port.write(b"x" * 100_000 + b"\r")
        time.sleep(0.5)
        port.reset_input_buffer()
        _drain(port)
        assert _answers_ver(port)
    assert emulator.troubles["full"] > LOG_LIMIT  # replies were dropped, many times
    assert emulator.troubles["line"] == 1
    assert len(caplog.records) <= LOG_BOUND
    assert emulator.serving
