"""The PHD ULTRA's language as message tables: framing, parsing, conversions and the
driver's exchanges, checked byte for byte with no port (after PyMeasure's
``expected_protocol``). Behaviour against the emulator is in test_phd_ultra.py."""

from __future__ import annotations

import contextlib
import math
import time

import pytest
from hypothesis import given
from hypothesis import strategies as st

from labrig.drivers.phd_ultra import PhdUltra
from labrig.drivers.phd_ultra_errors import (
    PumpArgumentError,
    PumpCommandError,
    PumpError,
    PumpLimitError,
    PumpModeError,
    PumpProtocolError,
    PumpRangeError,
    PumpTimeout,
    PumpUnknownCommand,
)
from labrig.drivers.phd_ultra_protocol import (
    agrees,
    candidate_address_forms,
    check_refusal,
    force_limit_pressure_kpa,
    format_rate,
    format_volume,
    frame_command,
    parse_can_withdraw,
    parse_diameter_mm,
    parse_force_pct,
    parse_identity,
    parse_mode,
    parse_rate_limits,
    parse_rate_ml_min,
    parse_reply,
    parse_status_line,
    parse_target_ml,
    parse_volume_ml,
    read_rate,
    read_volume,
)
from labrig.rig.devices import PumpState


class ScriptedPort:
    """A pyserial stand-in that plays a table of (sent, received) byte pairs.

    Every write must be the next ``sent``; its ``received`` bytes then become readable,
    ``chunk`` bytes per read. A pair with ``sent=None`` is bytes the pump sends by
    itself: they arrive once everything before them has been read.
    """

    port = "scripted"

    def __init__(self, pairs, chunk: int | None = None) -> None:
        self.pairs = list(pairs)
        self.pending = bytearray()
        self.chunk = chunk

    def _release(self) -> None:
        while not self.pending and self.pairs and self.pairs[0][0] is None:
            self.pending += self.pairs.pop(0)[1]

    def write(self, data: bytes) -> None:
        self._release()
        assert self.pairs, f"unexpected command {data!r}: the table is finished"
        sent, received = self.pairs.pop(0)
        assert data == sent, f"sent {data!r}, the table expects {sent!r}"
        self.pending += received

    @property
    def in_waiting(self) -> int:
        self._release()
        return min(len(self.pending), self.chunk or len(self.pending))

    def read(self, size: int) -> bytes:
        self._release()
        n = min(size, len(self.pending), self.chunk or size)
        if n == 0:
            time.sleep(0.001)  # a real port's read blocks for its timeout
        out = bytes(self.pending[:n])
        del self.pending[:n]
        return out

    def close(self) -> None:
        pass


@contextlib.contextmanager
def expected_protocol(pairs, *, chunk=None, **driver_options):
    """A driver on a ScriptedPort; on exit every pair must have been exchanged."""
    port = ScriptedPort(pairs, chunk=chunk)
    # These tables are in the two-digit form; finding the form is tested on its own.
    yield PhdUltra(port, **{"timeout_s": 0.05, "address_form": "digits", **driver_options})
    assert port.pairs == [], f"never exchanged: {port.pairs}"
    assert not port.pending, f"never read: {bytes(port.pending)!r}"


# ---- framing -----------------------------------------------------------------------


@pytest.mark.parametrize(
    ("command", "address", "form", "sent"),
    [
        ("irate", 0, "digits", b"00irate\r"),
        ("irate 10.0000 ml/min", 7, "digits", b"07irate 10.0000 ml/min\r"),
        ("irat 3.2 ul/min", 12, "colon", b"12:irat 3.2 ul/min\r"),
        ("ver", 0, "colon", b"0:ver\r"),
        ("ver", 0, "none", b"ver\r"),
    ],
)
def test_frame_command(command, address, form, sent):
    assert frame_command(command, address=address, address_form=form) == sent


def test_frame_command_rejects_an_address_beyond_the_chain():
    with pytest.raises(ValueError, match="0-99"):
        frame_command("ver", address=100)


@pytest.mark.parametrize(
    ("raw", "expect_payload", "lines", "prompt", "address"),
    [
        # Real PHD ULTRA replies quoted by chembot (address 0, echo off).
        (b"\n15.3477 ml/min\r\n:", True, ("15.3477 ml/min",), ":", None),
        (b"\n0 ul\r\n:", True, ("0 ul",), ":", None),
        (b"\n0 0 0 w..TI.\r\n:", True, ("0 0 0 w..TI.",), ":", None),
        (b"\n:", False, (), ":", None),
        # A non-zero address in front of the prompt; running and target prompts.
        (b"\n12>", False, (), ">", 12),
        (b"\n01T*", False, (), "T*", 1),
        (b"\nT:", False, (), "T:", None),
        # Each line prefixed with address and prompt (Elite-style firmware).
        (b"\n00:9.5250 mm\r\n00:", True, ("9.5250 mm",), ":", 0),
        (b"\n03<1.5 ml\r\n03<", True, ("1.5 ml",), "<", 3),
        # Multi-line reply; an error with its indented detail line.
        (
            b"\nFirmware: v3.0.5\r\nPump address: 0\r\nSerial number: D401460\r\n:",
            True,
            ("Firmware: v3.0.5", "Pump address: 0", "Serial number: D401460"),
            ":",
            None,
        ),
        (
            b"\nArgument error: [on]\r\n   Unknown argument\r\n:",
            False,
            ("Argument error: [on]", "Unknown argument"),
            ":",
            None,
        ),
        # Older firmware: the status line after its prompt.
        (b"\n:\n0 0 0 w..TI.\r\n", True, ("0 0 0 w..TI.",), ":", None),
        # An echo of the command before the first LF is not part of the reply.
        (b"00ivolume\r\n1.234 ml\r\n:", True, ("1.234 ml",), ":", None),
        # A target prompt leaked into the first line, and one received just before.
        (b"\nT*1.000 ml\r\nT*", True, ("1.000 ml",), "T*", None),
        (b"\nT*\n2.5 ml\r\n:", True, ("2.5 ml",), ":", None),
        # The target was reached just after the line was sent: its own prefix is '00>'.
        (b"\n00>0 994 4968 I..TI.\r\n00>\n00T*", True, ("0 994 4968 I..TI.",), "T*", 0),
        # A payload line that looks like time with the address in front stays whole.
        (b"\n00:00:01:40\r\n00:", True, ("00:01:40",), ":", 0),
    ],
)
def test_parse_complete_replies(raw, expect_payload, lines, prompt, address):
    reply = parse_reply(raw, expect_payload=expect_payload)
    assert reply is not None
    assert (reply.lines, reply.prompt, reply.address) == (lines, prompt, address)


@pytest.mark.parametrize(
    ("raw", "expect_payload"),
    [
        (b"", True),
        (b"\n15.34", True),  # a line still arriving
        (b"\n15.3477 ml/min\r", True),
        (b"\n15.3477 ml/min\r\n", True),  # the prompt is missing
        (b"\n:", True),  # a value was asked for and only the prompt came
        (b"\nT", False),  # half a target prompt
        (b"\n0", False),  # half an address
        (b"00ver\r", False),  # only the echo
    ],
)
def test_incomplete_replies_wait_for_more(raw, expect_payload):
    assert parse_reply(raw, expect_payload=expect_payload) is None


def test_a_reply_with_garbage_bytes_is_a_protocol_error():
    with pytest.raises(PumpProtocolError, match="unreadable reply"):
        parse_reply(b"\n\xfe\x81#\r\n15.3 ml/min\r\n:", expect_payload=True, command="irate")


@pytest.mark.parametrize(
    ("prompt", "state"),
    [
        (b":", PumpState.IDLE),
        (b">", PumpState.INFUSING),
        (b"<", PumpState.WITHDRAWING),
        (b"*", PumpState.STALLED),
        (b"T*", PumpState.TARGET_REACHED),
        (b"T:", PumpState.TARGET_REACHED),
        (b":T*", PumpState.TARGET_REACHED),
        (b"04:T*", PumpState.TARGET_REACHED),
    ],
)
def test_prompt_states(prompt, state):
    assert parse_reply(b"\n" + prompt, expect_payload=False).state is state


@pytest.mark.parametrize(
    ("raw", "expect_payload", "lines"),
    [
        (b"\n:\x11", False, ()),  # poll on: the reply that once never completed
        (b"\n15.3477 ml/min\r\n:\x11", True, ("15.3477 ml/min",)),
        (b"\x11\n100%\r\n>\x11", True, ("100%",)),  # an XON left from the last reply
        (b"\n5.0000 ml\r\n:T*\x11", True, ("5.0000 ml",)),
    ],
)
def test_xon_after_a_prompt_is_dropped(raw, expect_payload, lines):
    reply = parse_reply(raw, expect_payload=expect_payload)
    assert reply is not None and reply.lines == lines


@given(
    lines=st.lists(
        st.text(alphabet=st.characters(min_codepoint=0x20, max_codepoint=0x7E), max_size=20)
        .map(str.strip)
        # a payload line never starts like a prompt (the parser drops prompt prefixes)
        .filter(lambda line: line and line[0] not in "0123456789:<>*" and "T" not in line[:3]),
        max_size=3,
    ),
    prompt=st.sampled_from([":", ">", "<", "*", "T*", "T:", ":T*", "07:", "12:T*"]),
    xon_at=st.lists(st.integers(min_value=0, max_value=200), max_size=4),
)
def test_xon_anywhere_in_a_reply_changes_nothing(lines, prompt, xon_at):
    # poll on puts XON after the prompt; a byte left from the last reply can come first.
    raw = b"".join(b"\n" + line.encode() + b"\r" for line in lines) + b"\n" + prompt.encode()
    plain = parse_reply(raw, expect_payload=False)
    with_xon = bytearray(raw)
    for position in sorted(xon_at, reverse=True):
        with_xon.insert(min(position, len(with_xon)), 0x11)
    assert parse_reply(bytes(with_xon), expect_payload=False) == plain
    assert plain is not None and plain.lines == tuple(lines)


def test_the_force_reply_and_its_pressure():
    assert parse_force_pct("100%") == 100
    assert parse_force_pct(" 17 %") == 17
    for bad in ("0%", "101%", "50", "half"):
        with pytest.raises(PumpProtocolError):
            parse_force_pct(bad)
    # The figure: 75 lbf over a 27.6 mm plunger is ~560 kPa (by hand:
    # 333.62 N / (pi * 13.8 mm^2 = 598.28 mm^2) = 557.6 kPa); 17 % of it is 94.8 kPa.
    assert force_limit_pressure_kpa(100, 75 * 4.4482216, 27.6) == pytest.approx(557.6, abs=0.1)
    assert force_limit_pressure_kpa(17, 75 * 4.4482216, 27.6) == pytest.approx(94.8, abs=0.1)


def test_the_address_forms_tried_follow_the_manual_first():
    assert candidate_address_forms(0) == ("none", "digits")
    assert candidate_address_forms(12) == ("colon", "digits")  # never unaddressed: pump 0


def test_the_force_limit_is_set_and_read_back():
    table = [
        (b"00force 17\r", b"\n:"),
        (b"00force\r", b"\n17%\r\n:"),
        (b"00force 40\r", b"\n:"),
        (b"00force\r", b"\n100%\r\n:"),  # a pump that ignored the setting
    ]
    with expected_protocol(table) as pump:
        pump.set_force_limit(17)
        with pytest.raises(PumpError, match="force limit of 100 % after being set to 40 %"):
            pump.set_force_limit(40)
        for bad in (0, 101, 50.0, True):
            with pytest.raises(PumpLimitError):
                pump.set_force_limit(bad)


@pytest.mark.parametrize(
    ("text", "error"),
    [
        ("Command error: [diameter] / Not allowed while running", PumpCommandError),
        ("Command error: [bogus] / Unknown command", PumpUnknownCommand),
        ("Unknown command", PumpUnknownCommand),
        ("Argument error: [on] / Unknown argument", PumpArgumentError),
        ("Argument error: [500] / Out of range", PumpRangeError),
        ("Out of range", PumpRangeError),
        ("Range error: 1-4", PumpRangeError),
    ],
)
def test_error_texts_become_typed_exceptions_with_the_pumps_text(text, error):
    reply = parse_reply(
        b"".join(b"\n" + line.encode() + b"\r" for line in text.split(" / ")) + b"\n:",
        expect_payload=False,
    )
    with pytest.raises(error) as raised:
        check_refusal(reply, "irate 500 ml/min")
    assert type(raised.value) is error
    assert raised.value.pump_text == text
    assert raised.value.command == "irate 500 ml/min"


# ---- values ------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("text", "ml"),
    [
        ("0 ul", 0.0),
        ("1.234 ml", 1.234),
        ("834.5 ul", 0.8345),
        ("12 nl", 12e-9 * 1e3),
        ("5 pl", 5e-9),
    ],
)
def test_volumes_are_converted_to_ml(text, ml):
    assert parse_volume_ml(text) == pytest.approx(ml, rel=1e-12)


@pytest.mark.parametrize(
    ("text", "ml_min"),
    [
        ("15.3477 ml/min", 15.3477),
        ("14.7792 nl/min", 14.7792e-6),
        ("250 ul/min", 0.25),
        ("6 ml/hr", 0.1),
        ("30 ul/hr", 0.0005),
    ],
)
def test_rates_are_converted_to_ml_per_min(text, ml_min):
    assert parse_rate_ml_min(text) == pytest.approx(ml_min, rel=1e-12)


def test_other_values():
    assert parse_diameter_mm("9.5250 mm") == 9.525
    assert parse_rate_limits("14.7792 nl/min to 15.3477 ml/min") == pytest.approx(
        (14.7792e-6, 15.3477)
    )
    assert parse_target_ml("5 ml") == 5.0
    assert parse_target_ml("Target volume not set") is None


def test_status_line_fields_in_femtolitres():
    # 1 mL = 1e12 fL: 1 mL/min = 1e12 fL / 60 s; 2.5 mL = 2.5e12 fL.
    line = parse_status_line("16666666667 150 2500000000000 I..TI.")
    assert line.rate_ml_min == pytest.approx(1.0, rel=1e-9)
    assert line.volume_ml == pytest.approx(2.5)
    assert line.time_s == 150  # seconds: the manual's "infuse time in seconds"
    assert (line.direction, line.running, line.stalled, line.target_reached) == (
        "i",
        True,
        False,
        False,
    )
    stalled = parse_status_line("0 0 0 w.STI.")
    assert (stalled.direction, stalled.running, stalled.stalled) == ("w", False, True)
    assert parse_status_line("0 10 5 i..TIT").target_reached
    # The manual's five flags (no target flag) are read too.
    assert not parse_status_line("0 0 0 i..TI").target_reached


@pytest.mark.parametrize(
    ("parse", "text"),
    [
        (parse_volume_ml, "1.234"),
        (parse_volume_ml, "1.234 ml/min"),
        (parse_rate_ml_min, "15 ml"),
        (parse_rate_ml_min, "fast"),
        (parse_diameter_mm, "9.5 in"),
        (parse_rate_limits, "15 ml/min"),
        (parse_rate_limits, "15 ml/min to 1 ml/min"),
        (parse_status_line, "0 0 w..TI."),
    ],
)
def test_unreadable_values_are_protocol_errors(parse, text):
    with pytest.raises(PumpProtocolError):
        parse(text)


@pytest.mark.parametrize(
    ("rate_ml_min", "text"),
    [
        (10.0, "10.0000 ml/min"),
        (0.25, "250.0000 ul/min"),
        (0.0000147792, "14.7792 nl/min"),
        (120.5968, "120.5968 ml/min"),
    ],
)
def test_format_rate(rate_ml_min, text):
    assert format_rate(rate_ml_min) == text


def test_format_volume():
    assert format_volume(5.0) == "5.0000 ml"
    assert format_volume(0.002) == "2.0000 ul"
    assert format_volume(0.0000005) == "0.5000 nl"
    assert format_volume(0.0000005, smallest="ul") == "0.0005 ul"


@given(st.floats(min_value=1e-6, max_value=1e3))
def test_a_formatted_rate_reads_back_within_its_rounding(rate_ml_min):
    # 4 decimals of a number >= 1: relative error at most 5e-5.
    assert math.isclose(parse_rate_ml_min(format_rate(rate_ml_min)), rate_ml_min, rel_tol=5e-5)


# ---- the driver's exchanges ----------------------------------------------------------

IDLE = (b"00status\r", b"\n0 0 0 i..TI.\r\n:")
# a stop, confirmed by two status polls showing the motor standing, the counter unchanged
STOPPED = [(b"00stop\r", b"\n:"), IDLE, IDLE]
VERSION = b"\nFirmware:      v3.0.5\r\nPump address:  0\r\nSerial number: D401460\r\n:"
# what connect reads before it sends anything the pump could refuse, and its stop
LOOKED_AT = [
    (b"00poll off\r", b"\n:"),
    (b"00ver\r", b"\nPHD ULTRA 3.0.5\r\n:"),
    IDLE,
    (b"00version\r", VERSION),
    (b"00mode\r", b"\nQuick Start Infuse/Withdraw\r\n:"),
    *STOPPED,
]
NVRAM_OFF = (b"00nvram off\r", b"\n:")
METRICS = (
    b"00metrics\r",
    b"\nPump type          PHD ULTRA\r\nDirection          Infuse/withdraw\r\n:",
)
SYRINGE = [(b"00diameter\r", b"\n26.7000 mm\r\n:"), (b"00svolume\r", b"\n60 ml\r\n:")]
CONNECT = [*LOOKED_AT, NVRAM_OFF, METRICS, *SYRINGE]
INFUSE_LIMITS = (b"00irate lim\r", b"\n116.1297 nl/min to 120.5968 ml/min\r\n:")
WITHDRAW_LIMITS = (b"00wrate lim\r", b"\n116.1297 nl/min to 120.5968 ml/min\r\n:")
LIMITS = [INFUSE_LIMITS, WITHDRAW_LIMITS]


@pytest.mark.parametrize("chunk", [None, 1, 5])
def test_connect_identifies_switches_off_nvram_and_reads_the_syringe(chunk):
    with expected_protocol(CONNECT, chunk=chunk) as pump:
        pump.connect()
    assert pump.firmware == "PHD ULTRA 3.0.5"
    assert (pump.syringe.diameter_mm, pump.syringe.volume_ml) == (26.7, 60.0)


def test_nvram_falls_back_to_the_other_argument():
    table = [
        *LOOKED_AT,
        (b"00nvram off\r", b"\nArgument error: [off]\r\n   Unknown argument\r\n:"),
        (b"00nvram none\r", b"\n:"),
        METRICS,
        *SYRINGE,
    ]
    with expected_protocol(table) as pump:
        pump.connect()
    assert pump.nvram_off_command == "nvram none"
    assert pump.connect_warnings == []


def test_connect_warns_and_goes_on_when_no_nvram_form_is_accepted():
    unknown = b"\nCommand error: [nvram]\r\n   Unknown command\r\n:"
    table = [
        *LOOKED_AT,
        (b"00nvram off\r", b"\nArgument error: [off]\r\n   Unknown argument\r\n:"),
        (b"00nvram none\r", unknown),
        (b"00rsave off\r", b"\nCommand error: [rsave]\r\n   Unknown command\r\n:"),
        METRICS,
        *SYRINGE,
    ]
    with expected_protocol(table) as pump:
        pump.connect()
    assert pump.nvram_off_command is None
    [warning] = pump.connect_warnings
    assert "'rsave off': Command error: [rsave] / Unknown command" in warning
    assert "memory is written at every setting change" in warning


def test_an_infuse_only_pump_is_asked_nothing_about_withdrawing():
    table = [
        *LOOKED_AT,
        NVRAM_OFF,
        (b"00metrics\r", b"\nPump type          PHD ULTRA\r\nDirection          Infuse only\r\n:"),
        *SYRINGE,
        INFUSE_LIMITS,
        (b"00irate 10.0000 ml/min\r", b"\n:"),
        (b"00irate\r", b"\n10.0000 ml/min\r\n:"),
        (b"00status\r", b"\n0 0 0 i..TI.\r\n:"),
        (b"00ivolume\r", b"\n0.3000 ml\r\n:"),
    ]
    with expected_protocol(table) as pump:
        pump.connect()
        assert not pump.can_withdraw
        pump.set_infuse_rate(10.0)
        assert pump.rate_limits().withdraw_ml_min is None
        assert pump.status().withdrawn_ml == 0.0
        with pytest.raises(PumpCommandError, match=r"infuse-only.*nothing was sent"):
            pump.set_withdraw_rate(1.0)
        with pytest.raises(PumpCommandError, match="infuse-only"):
            pump.withdraw()


def test_a_rate_is_sent_and_read_back_in_whatever_unit_the_pump_answers():
    table = [
        INFUSE_LIMITS,
        (b"00irate 10.0000 ml/min\r", b"\n:"),
        (b"00irate\r", b"\n10000.0 ul/min\r\n:"),
        WITHDRAW_LIMITS,
        (b"00wrate 250.0000 ul/min\r", b"\n:"),
        (b"00wrate\r", b"\n15 ml/hr\r\n:"),
    ]
    with expected_protocol(table) as pump:
        pump.set_infuse_rate(10.0)
        pump.set_withdraw_rate(0.25)


def test_a_rate_outside_the_syringe_limits_is_refused_before_sending():
    # Only the limits are asked: no irate/wrate command is in the table.
    with expected_protocol(LIMITS) as pump:
        with pytest.raises(PumpLimitError, match="outside this syringe's limits") as raised:
            pump.set_infuse_rate(150.0)
        assert raised.value.exit_code == 2
        with pytest.raises(PumpLimitError):
            pump.set_withdraw_rate(50e-6)
        with pytest.raises(PumpLimitError):
            pump.set_infuse_rate(float("nan"))


def test_a_readback_that_differs_from_the_setting_is_an_error():
    table = [
        INFUSE_LIMITS,
        (b"00irate 10.0000 ml/min\r", b"\n:"),
        (b"00irate\r", b"\n1.0000 ml/min\r\n:"),
    ]
    with (
        expected_protocol(table) as pump,
        pytest.raises(PumpError, match=r"reports infuse rate '1\.0000 ml/min'"),
    ):
        pump.set_infuse_rate(10.0)


def test_the_pumps_refusal_reaches_the_caller_with_its_text():
    table = [
        INFUSE_LIMITS,
        (b"00irate 100.0000 ml/min\r", b"\nArgument error: [100.0000]\r\n   Out of range\r\n:"),
    ]
    with expected_protocol(table) as pump, pytest.raises(PumpRangeError) as raised:
        pump.set_infuse_rate(100.0)
    assert raised.value.pump_text == "Argument error: [100.0000] / Out of range"


def test_syringe_configuration_target_and_clear():
    table = [
        (b"00diameter 14.5700\r", b"\n:"),
        (b"00svolume 10.0000 ml\r", b"\n:"),
        (b"00diameter\r", b"\n14.5700 mm\r\n:"),
        (b"00svolume\r", b"\n10 ml\r\n:"),
        (b"00tvolume 2.5000 ml\r", b"\n:"),
        (b"00tvolume\r", b"\n2500 ul\r\n:"),
        (b"00cvolume\r", b"\n:"),
        (b"00ctvolume\r", b"\n:"),
        (b"00tvolume\r", b"\nTarget volume not set\r\n:"),
    ]
    with expected_protocol(table) as pump:
        pump.configure_syringe(14.57, 10.0)
        pump.set_target_volume(2.5)
        pump.clear_volumes()
        assert pump.target_volume_ml() is None


def test_run_commands_must_show_the_running_prompt():
    table = [
        (b"00irun\r", b"\n>"),
        (b"00wrun\r", b"\n<"),
        (b"00irun\r", b"\nT*"),  # the target was already met: the run ended at once
        (b"00irun\r", b"\n:"),
    ]
    with expected_protocol(table) as pump:
        pump.infuse()
        pump.withdraw()
        pump.infuse()
        with pytest.raises(PumpError, match="did not start"):
            pump.infuse()


def test_stop_must_leave_the_motor_standing():
    running = (b"00status\r", b"\n100000000000 3 300000000000 I..TI.\r\n>")
    # stopped; then a stop answered ':' whose status polls show the motor running, a
    # second stop, still running: no prompt character alone confirms a stop
    table = [*STOPPED, (b"00stop\r", b"\n:"), running, (b"00stop\r", b"\n>"), running]
    with expected_protocol(table) as pump:
        pump.stop()
        with pytest.raises(PumpError, match="still reports infusing"):
            pump.stop()


@pytest.mark.parametrize(
    ("status_reply", "prompt", "state"),
    [
        (b"\n100000000000 3000 300000000000 I..TI.\r\n>", b">", PumpState.INFUSING),
        (b"\n>\n100000000000 3000 300000000000 I..TI.\r\n", b">", PumpState.INFUSING),
        (b"\n0 3000 300000000000 i.STI.\r\n*", b"*", PumpState.STALLED),
        (b"\n0 3000 300000000000 i.STI.\r\n:", b":", PumpState.STALLED),
        (b"\n0 3000 300000000000 i..TIT\r\nT*", b"T*", PumpState.TARGET_REACHED),
        (b"\n0 3000 300000000000 i..TIT\r\n:", b":", PumpState.TARGET_REACHED),
        (b"\n0 3000 300000000000 w..TI.\r\n:", b":", PumpState.IDLE),
    ],
)
def test_status_from_prompt_flags_and_counters(status_reply, prompt, state):
    table = [
        (b"00status\r", status_reply),
        (b"00ivolume\r", b"\n300.0000 ul\r\n" + prompt),
        (b"00wvolume\r", b"\n0 ul\r\n" + prompt),
    ]
    with expected_protocol(table) as pump:
        status = pump.status()
    assert status.state is state
    assert (status.infused_ml, status.withdrawn_ml) == (pytest.approx(0.3), 0.0)


def test_an_unsolicited_target_prompt_is_discarded_before_the_next_command():
    table = [(None, b"\nT*"), (b"00ver\r", b"\nPHD ULTRA 3.0.5\r\nT*")]
    with expected_protocol(table) as pump:
        assert pump.identify() == "PHD ULTRA 3.0.5"


def test_addresses_in_both_forms_and_a_reply_from_another_pump():
    with expected_protocol(
        [(b"12:ver\r", b"\nPHD ULTRA 3.0.5\r\n12:")], address=12, address_form="colon"
    ) as pump:
        assert pump.identify() == "PHD ULTRA 3.0.5"
    idle = (b"05status\r", b"\n0 0 0 i..TI.\r\n05:")
    table = [(b"05ver\r", b"\nPHD ULTRA 3.0.5\r\n07:"), (b"05stop\r", b"\n05:"), idle, idle]
    with (
        expected_protocol(table, address=5) as pump,
        pytest.raises(PumpProtocolError, match="from pump address 7"),
    ):
        pump.identify()


def test_no_reply_times_out_and_the_driver_stops_the_pump():
    # the stop written at once (its reply discarded with any late one), then a second
    # stop whose reply is read
    table = [(b"00ivolume\r", b""), (b"00stop\r", b"\n:"), *STOPPED]
    with expected_protocol(table) as pump, pytest.raises(PumpTimeout) as raised:
        pump.volumes_ml()
    assert "'ivolume'" in str(raised.value)
    assert "the pump was stopped" in str(raised.value)


def test_a_garbled_reply_is_a_protocol_error_and_the_driver_stops_the_pump():
    table = [(b"00ivolume\r", b"\n\xff\xfe\x93\r\n12.5 ml\r\n>"), *STOPPED]
    with expected_protocol(table) as pump, pytest.raises(PumpProtocolError) as raised:
        pump.volumes_ml()
    assert "the pump was stopped" in str(raised.value)


def test_a_value_where_none_belongs_is_a_protocol_error():
    table = [(b"00cvolume\r", b"\n12.5 ml\r\n:"), *STOPPED]
    with expected_protocol(table) as pump, pytest.raises(PumpProtocolError, match="unexpected"):
        pump.clear_volumes()


# ---- what was unverified: units, status time, withdraw capability, readbacks ---------


@pytest.mark.parametrize(
    ("text", "value", "half_step"),
    [
        ("60 ml", 60.0, 0.5),
        ("60.0000 ml", 60.0, 0.00005),
        ("500 ul", 0.5, 0.0005),
        ("1.5e-3 ml", 0.0015, 0.05e-3),
    ],
)
def test_a_volume_is_read_with_the_resolution_it_was_printed_with(text, value, half_step):
    reading = read_volume(text)
    assert reading.value == pytest.approx(value, rel=1e-12)
    assert reading.half_step == pytest.approx(half_step, rel=1e-12)


@pytest.mark.parametrize(
    ("text", "ml_min"),
    [("2 ml/hr", 2 / 60), ("2 ml/h", 2 / 60), ("3 ul/sec", 0.18), ("0.5 ml/s", 30.0)],
)
def test_the_time_bases_a_pump_prints(text, ml_min):
    assert read_rate(text).value == pytest.approx(ml_min, rel=1e-12)


def test_units_are_ascii_a_micro_sign_is_a_protocol_error():
    # 'ul' is how the pump writes microlitres; a non-ASCII byte is line noise.
    assert parse_volume_ml(parse_reply(b"\n834.5 ul\r\n:", expect_payload=True).text) == 0.8345
    with pytest.raises(PumpProtocolError):
        parse_reply("\n834.5 µl\r\n:".encode("latin-1"), expect_payload=True)


@pytest.mark.parametrize(
    ("sent", "reply", "agreed"),
    [
        ("60.0000 ml", "60 ml", True),  # fewer digits printed
        ("250.0000 ul/min", "0.25 ml/min", True),  # another unit
        ("123.4500 ul/min", "0.12 ml/min", True),  # it shows no more digits
        ("10.0000 ml/min", "10.005 ml/min", False),  # 5e-4 relative: a real difference
        ("5.0000 ml", "5.0002 ml", False),
    ],
)
def test_a_readback_agrees_to_the_digits_both_were_printed_with(sent, reply, agreed):
    reader = read_rate if "/" in sent else read_volume
    assert agrees(reader(reply), reader(sent)) is agreed


def test_a_readback_with_more_precision_than_a_fixed_tolerance_is_refused():
    table = [
        INFUSE_LIMITS,
        (b"00irate 10.0000 ml/min\r", b"\n:"),
        (b"00irate\r", b"\n10.005 ml/min\r\n:"),
    ]
    with expected_protocol(table) as pump, pytest.raises(PumpError, match=r"10\.005 ml/min"):
        pump.set_infuse_rate(10.0)


@pytest.mark.parametrize(
    ("lines", "can_withdraw"),
    [
        (("Pump type          Pump 11", "Direction          Infuse/withdraw"), True),
        (("Direction          Infuse only",), False),
        (("Direction          Infuse",), False),
        (("Pump type          Pump 11",), None),
    ],
)
def test_the_direction_line_of_metrics(lines, can_withdraw):
    assert parse_can_withdraw(lines) is can_withdraw


def test_a_pump_that_does_not_say_whether_it_withdraws_is_asked_and_warned_about():
    table = [
        *LOOKED_AT,
        NVRAM_OFF,
        (b"00metrics\r", b"\nCommand error: [metrics]\r\n   Unknown command\r\n:"),
        (b"00wvolume\r", b"\n0 ul\r\n:"),
        *SYRINGE,
        WITHDRAW_LIMITS,  # an infuse-only pump would refuse this: before anything moves
        (b"00wrate 1.0000 ml/min\r", b"\n:"),
        (b"00wrate\r", b"\n1 ml/min\r\n:"),
    ]
    with expected_protocol(table) as pump:
        pump.connect()
        assert pump.can_withdraw
        [warning] = pump.connect_warnings
        assert "does not say whether it withdraws" in warning
        assert "refused 'metrics'" in warning
        assert "answers 'wvolume', so it is taken as withdrawing" in warning
        pump.set_withdraw_rate(1.0)


def test_the_status_time_is_in_seconds_as_the_manual_gives_it():
    # 30 s at 1 mL/min: 0.5 mL; read as ms it would be 0.03 s for 0.5 mL (1000 mL/min)
    line = parse_status_line("16666666667 30 500000000000 I..TI.")
    assert line.time_s == 30
    assert line.volume_ml / (line.time_s / 60) == pytest.approx(line.rate_ml_min, rel=1e-9)


# ---- the pump as the bench leaves it: read first, then stopped and put in Quick Start --


def connect_table(status=IDLE[1], mode=b"\nQuick Start Infuse/Withdraw\r\n:", after=()):
    """Connect's exchanges with the pump's ``status`` and ``mode`` replies given, and
    ``after`` between its stop and the syringe (default: NVRAM and metrics)."""
    return [
        *LOOKED_AT[:2],
        (b"00status\r", status),
        (b"00version\r", VERSION),
        (b"00mode\r", mode),
        *STOPPED,
        *(after or (NVRAM_OFF, METRICS)),
        *SYRINGE,
    ]


def test_a_pump_found_infusing_is_stopped_and_the_operator_told_what_it_did():
    # 6 mL/min = 1e11 fL/s; 2.35 mL on its infused counter
    table = connect_table(status=b"\n100000000000 23 2350000000000 I..TI.\r\n>")
    with expected_protocol(table) as pump:
        pump.connect()
    [notice] = pump.connect_notices
    assert notice.startswith("the pump was infusing at 6 mL/min (2.3500 mL infused on its counter)")
    assert notice.endswith("labrig stopped it (stop confirmed by its status)")
    assert pump.run_record["at_connect"] == notice


def test_a_pump_found_withdrawing_says_withdrawn():
    table = connect_table(status=b"\n50000000000 2 100000000000 W..TI.\r\n<")
    with expected_protocol(table) as pump:
        pump.connect()
    assert "withdrawing at 3 mL/min (0.1000 mL withdrawn" in pump.connect_notices[0]


@pytest.mark.parametrize(
    ("status", "said"),
    [
        (b"\n0 60 1000000000000 i..TIT\r\nT*", "the pump was target reached (its alarm on)"),
        (b"\n0 60 1000000000000 i.STI.\r\n*", "the pump was stalled (its alarm on)"),
    ],
)
def test_a_pump_found_with_its_alarm_on_is_stopped_and_told(status, said):
    with expected_protocol(connect_table(status=status)) as pump:
        pump.connect()
    assert pump.connect_notices[0].startswith(said)


def test_a_pump_in_a_method_standing_in_a_pause_is_stopped_and_put_in_quick_start():
    """Idle by its prompt and its flags, but its method will move it again: the stop
    goes first, then ``load qs iw``, read back."""
    table = connect_table(
        mode=b"\nMethod prime\r\n:",
        after=[
            NVRAM_OFF,
            METRICS,
            (b"00load qs iw\r", b"\n:"),
            (b"00mode\r", b"\nQuick Start Infuse/Withdraw\r\n:"),
        ],
    )
    with expected_protocol(table) as pump:
        pump.connect()
    stopped, loaded = pump.connect_notices
    assert stopped.startswith("the pump was in a method ('Method prime'), standing")
    assert loaded == (
        "labrig loaded Quick Start on the pump ('load qs iw'): it was in 'Method prime'"
    )


@pytest.mark.parametrize(
    ("mode", "infuse_only", "loaded"),
    [
        (b"Quick Start Infuse", False, b"iw"),
        (b"Quick Start Withdraw", False, b"iw"),
        (b"Quick Start Withdraw", True, b"i"),
        (b"Quick Start Infuse", True, None),
        (b"Quick Start Withdraw/Infuse", False, None),
    ],
)
def test_the_quick_start_variant_labrig_needs_is_loaded_when_missing(mode, infuse_only, loaded):
    metrics = METRICS
    if infuse_only:
        metrics = (b"00metrics\r", b"\nDirection          Infuse only\r\n:")
    after = [NVRAM_OFF, metrics]
    name = {b"i": b"Infuse", b"iw": b"Infuse/Withdraw"}
    if loaded is not None:
        after += [
            (b"00load qs " + loaded + b"\r", b"\n:"),
            (b"00mode\r", b"\nQuick Start " + name[loaded] + b"\r\n:"),
        ]
    with expected_protocol(connect_table(mode=b"\n" + mode + b"\r\n:", after=after)) as pump:
        pump.connect()
    assert len(pump.connect_notices) == (loaded is not None)


def test_a_pump_that_will_not_leave_its_method_is_refused_in_one_line():
    after = [
        NVRAM_OFF,
        METRICS,
        (b"00load qs iw\r", b"\nCommand error: [load]\r\n   Method locked\r\n:"),
    ]
    table = connect_table(mode=b"\nMethod prime\r\n:", after=after)[:-2]  # no syringe read
    with expected_protocol(table) as pump, pytest.raises(PumpModeError) as raised:
        pump.connect()
    message = str(raised.value)
    assert "\n" not in message
    assert "is in 'Method prime' and refused 'load qs iw': Command error" in message
    assert "on its panel, stop any method" in message
    assert "Quick Start, then Infuse/Withdraw" in message


def test_looking_at_a_pump_leaves_it_running():
    """``pump status``: no stop, no mode change; the rest of connect as always."""
    table = [
        *LOOKED_AT[:2],
        (b"00status\r", b"\n100000000000 23 2350000000000 I..TI.\r\n>"),
        (b"00version\r", VERSION.replace(b":", b">")),
        (b"00mode\r", b"\nQuick Start Infuse\r\n>"),
        (b"00nvram off\r", b"\n>"),
        (b"00metrics\r", METRICS[1].replace(b"\n:", b"\n>")),
        (b"00diameter\r", b"\n26.7000 mm\r\n>"),
        (b"00svolume\r", b"\n60 ml\r\n>"),
    ]
    with expected_protocol(table) as pump:
        pump.connect(take_control=False)
    assert pump.connect_notices == []


def test_a_pump_that_does_not_say_and_refuses_wvolume_cannot_withdraw():
    """Infuse-only firmware whose ``metrics`` has no Direction line: the refused
    ``wvolume`` says it, with a warning; no withdraw command is sent after."""
    after = [
        NVRAM_OFF,
        (b"00metrics\r", b"\nPump type          PHD ULTRA\r\n:"),
        (b"00wvolume\r", b"\nCommand error: [wvolume]\r\n   Unknown command\r\n:"),
    ]
    table = [
        *connect_table(after=after),
        (b"00status\r", b"\n0 0 0 i..TI.\r\n:"),
        (b"00ivolume\r", b"\n0 ul\r\n:"),
    ]
    with expected_protocol(table) as pump:
        pump.connect()
        assert not pump.can_withdraw
        [warning] = pump.connect_warnings
        assert "no Direction line" in warning and "refused 'wvolume'" in warning
        assert "it cannot withdraw" in warning
        assert pump.status().withdrawn_ml == 0.0


def test_a_stop_is_confirmed_by_the_counter_standing_not_by_the_prompt():
    """The prompt says idle at once, the counter still creeps (a motor coasting, flags
    that lag): polled until two polls agree."""
    table = [
        (b"00stop\r", b"\n:"),
        (b"00status\r", b"\n0 3 300000000000 i..TI.\r\n:"),
        (b"00status\r", b"\n0 3 300100000000 i..TI.\r\n:"),
        (b"00status\r", b"\n0 3 300100000000 i..TI.\r\n:"),
    ]
    with expected_protocol(table) as pump:
        pump.stop()
    creeping = [(b"00stop\r", b"\n:")] + [
        (b"00status\r", b"\n0 3 30%d000000000 i..TI.\r\n:" % i) for i in range(4)
    ]
    with expected_protocol(creeping) as pump, pytest.raises(PumpError, match="not confirmed"):
        pump.stop()


def test_the_pumps_identity_from_its_version_reply():
    identity = parse_identity(
        "PHD ULTRA 3.0.5",
        ("Firmware:      v3.0.5", "Pump address:  12", "Serial number: D401460"),
    )
    assert (identity.model, identity.firmware) == ("PHD ULTRA", "3.0.5")
    assert (identity.serial_number, identity.address) == ("D401460", 12)
    assert identity.describe() == "PHD ULTRA 3.0.5, serial D401460, address 12"
    bare = parse_identity("PHD ULTRA 3.0.5", ("Firmware: v3.0.5",))
    assert (bare.serial_number, bare.address) == (None, None)
    assert bare.describe() == "PHD ULTRA 3.0.5, serial no serial number, address ?"


@pytest.mark.parametrize(
    ("text", "variant"),
    [
        ("Quick Start Infuse", "i"),
        ("Quick Start Withdraw", "w"),
        ("Quick Start Infuse/Withdraw", "iw"),
        ("quick start withdraw/infuse", "wi"),
        ("Method prime", None),
        ("Quick Start Something", None),
    ],
)
def test_the_mode_reply(text, variant):
    assert parse_mode(text) == variant
