"""The public clients' sequences (``support.pump_clients``: what each sends, byte for
byte, and what comes back) against the emulator and the driver.

Every table runs against the emulator on a real pseudo-terminal (plain pyserial, on a
virtual clock so the volumes are exact), and every answer in it is read again by the
driver's parser: a reply the emulator gives a client must be one the driver reads too.
"""

from __future__ import annotations

import pytest
import serial
from support.pump_clients import (
    CHEMBOT_INFUSE,
    FLOWCHEM_ELITE11,
    METRICS,
    SEQUENCES,
    WAIT,
)

from labrig.drivers.phd_ultra_errors import PumpCommandError
from labrig.drivers.phd_ultra_protocol import (
    check_refusal,
    parse_can_withdraw,
    parse_diameter_mm,
    parse_rate_limits,
    parse_rate_ml_min,
    parse_reply,
    parse_status_line,
    parse_target_ml,
    parse_volume_ml,
)
from labrig.sim.pump import PumpEmulator
from labrig.sim.pump_commands import COMMANDS
from labrig.sim.pump_firmware import REAL_ADDRESSING, PumpFirmware
from labrig.time.virtual import VirtualClock


def transact(port: serial.Serial, sent: bytes, expected: bytes) -> bytes:
    """Send ``sent`` (if any) and read as many bytes as ``expected`` holds."""
    if sent:
        port.write(sent)
    return port.read(len(expected))


def replay(emulator: PumpEmulator, clock: VirtualClock, table) -> None:
    with serial.Serial(emulator.port, 115200, timeout=2.0) as port:
        for sent, expected in table:
            if sent == WAIT:
                clock.sleep(expected)
                continue
            assert transact(port, sent, expected) == expected, sent
        port.timeout = 0.05
        assert port.read(64) == b"", "bytes after the last reply"


@pytest.mark.parametrize("name", SEQUENCES)
def test_a_clients_sequence_byte_for_byte_on_a_pseudo_terminal(name):
    table, options = SEQUENCES[name]
    clock = VirtualClock()
    # the addressing real pumps take: none or 0/00 at address 0
    with PumpEmulator(clock, strict_address_form=REAL_ADDRESSING, **options) as emulator:
        replay(emulator, clock, table)


# What the driver's parser makes of each answer, by the command it answers.
VALUE_READERS = {
    "irate": parse_rate_ml_min,
    "ivolume": parse_volume_ml,
    "wvolume": parse_volume_ml,
    "svol": parse_volume_ml,
    "tvolume": parse_target_ml,
    "diameter": parse_diameter_mm,
    "status": parse_status_line,
    "metrics": lambda text: parse_can_withdraw(tuple(text.split(" / "))),
}


def _word(sent: bytes) -> str:
    """The command word of a client's line: address digits and '@' dropped."""
    text = sent.decode().strip().lstrip("0123456789:@").split(" ")[0]
    return text.lower()


@pytest.mark.parametrize("name", SEQUENCES)
def test_the_driver_reads_every_answer_a_client_gets(name):
    table, _ = SEQUENCES[name]
    read = 0
    for sent, received in table:
        if sent == WAIT:
            continue
        reply = parse_reply(received, expect_payload=False)
        assert reply is not None, received  # complete as it stands
        if b"error" in received:
            with pytest.raises(PumpCommandError):
                check_refusal(reply, sent.decode())
            continue
        check_refusal(reply, sent.decode())
        word = _word(sent)
        if reply.lines and word in VALUE_READERS:
            if word == "irate" and b" lim" in sent:
                parse_rate_limits(reply.text)
            else:
                assert VALUE_READERS[word](reply.text) is not None, received
            read += 1
    assert read >= 2  # each sequence reads values, not prompts only


def test_the_values_clients_read_are_the_ones_they_set():
    """The flowchem and chembot answers, read by the driver, against hand figures."""
    by_sent = dict(row for row in FLOWCHEM_ELITE11 + CHEMBOT_INFUSE if row[0] != WAIT)

    def text(sent: bytes) -> str:
        return parse_reply(by_sent[sent], expect_payload=True).text

    assert parse_rate_ml_min(text(b"0irate \r\n")) == pytest.approx(0.5)  # 0.5 m/m
    assert parse_volume_ml(text(b"0ivolume \r\n")) == pytest.approx(0.5 * 6 / 60)
    assert parse_can_withdraw(parse_reply(METRICS, expect_payload=True).lines) is True
    line = parse_status_line(text(b"@status\r"))
    assert (line.time_s, line.volume_ml, line.target_reached) == (60, pytest.approx(1.0), True)


# ---- the command list ----------------------------------------------------------------


def test_the_emulator_answers_exactly_the_command_table():
    firmware = PumpFirmware(VirtualClock())
    assert firmware.commands == {command.name for command in COMMANDS}


@pytest.mark.parametrize("command", COMMANDS, ids=lambda command: command.name)
def test_every_listed_command_is_known_in_full_and_by_four_letters(command):
    firmware = PumpFirmware(VirtualClock())
    for word in {command.name, command.name[:4]}:
        answer = firmware.execute(f"{word} ?")  # a bad argument, or ignored: still known
        assert answer is not None
        assert "Unknown command" not in " ".join(answer.lines), word
        expected = "syrm" if word == "syrm" else command.name
        assert answer.command == expected
