"""The emulator's command set on its own (no serial line): numbers and units as the
firmware reads and prints them, and the commands that act on the plunger over time
(target time, ramps, the time counters), each against a hand calculation."""

from __future__ import annotations

import pytest

from labrig.rig.devices import PumpState
from labrig.sim.pump_firmware import PumpFirmware
from labrig.sim.pump_units import number_text, read_rate_ml_min, read_volume_ml
from labrig.time.virtual import VirtualClock


@pytest.mark.parametrize(
    ("value", "text"),
    [
        (60.0, "60"),
        (10.0, "10"),
        (15.34771, "15.3477"),
        (14.7792, "14.7792"),
        (120.5968, "120.597"),  # six significant digits
        (0.000015, "0.000015"),
        (1234.5, "1234.5"),
        (0.0, "0"),
    ],
)
def test_numbers_print_with_six_significant_digits_and_no_trailing_zeros(value, text):
    assert number_text(value) == text


# mL per unit and minutes per time base, written out by hand
VOLUME_SPELLINGS = {"ml": 1, "m": 1, "ML": 1, "ul": 1e-3, "u": 1e-3, "nl": 1e-6, "n": 1e-6}
TIME_SPELLINGS = {"min": 1, "m": 1, "hr": 60, "h": 60, "H": 60, "sec": 1 / 60, "s": 1 / 60}


@pytest.mark.parametrize("volume", VOLUME_SPELLINGS)
@pytest.mark.parametrize("time_base", TIME_SPELLINGS)
def test_every_rate_spelling_is_read(volume, time_base):
    rate_ml_min, _ = read_rate_ml_min("3", f"{volume}/{time_base}")
    expected = 3 * VOLUME_SPELLINGS[volume] / TIME_SPELLINGS[time_base]
    assert rate_ml_min == pytest.approx(expected, rel=1e-12)


@pytest.mark.parametrize("unit", ["ml", "m", "ul", "u", "nl", "n", "pl", "p", "Ml"])
def test_every_volume_spelling_is_read(unit):
    factor = {"m": 1, "u": 1e-3, "n": 1e-6, "p": 1e-9}[unit[0].lower()]
    assert read_volume_ml("2", unit)[0] == pytest.approx(2 * factor, rel=1e-12)


def run(firmware: PumpFirmware, clock: VirtualClock, seconds: float, step_s: float = 0.1):
    """Let ``seconds`` of clock time pass, ticking as the emulator's timer does."""
    for _ in range(round(seconds / step_s)):
        clock.sleep(step_s)
        firmware.tick(clock.now())


def ask(firmware: PumpFirmware, command: str) -> str:
    return " / ".join(firmware.execute(command).lines)


def test_a_target_time_ends_the_run_exactly():
    clock = VirtualClock()
    firmware = PumpFirmware(clock)
    assert ask(firmware, "irate 6 ml/min") == ""  # 0.1 mL/s
    assert ask(firmware, "ttime 00:01:40") == ""
    assert ask(firmware, "ttime") == "00:01:40"
    ask(firmware, "irun")
    clock.sleep(250.0)
    assert firmware.state is PumpState.TARGET_REACHED
    assert ask(firmware, "ivolume") == "10 ml"  # 100 s at 0.1 mL/s
    assert ask(firmware, "itime") == "00:01:40"
    assert ask(firmware, "status") == "0 100 10000000000000 i..TIT"
    # whichever target comes first ends the next run: 2 mL at 0.1 mL/s is 20 s
    ask(firmware, "stop")
    ask(firmware, "cvolume")
    ask(firmware, "ctime")
    ask(firmware, "tvolume 2 m")
    ask(firmware, "irun")
    clock.sleep(250.0)
    assert (ask(firmware, "ivolume"), ask(firmware, "itime")) == ("2 ml", "20 seconds")


def test_clearing_the_times_leaves_the_volumes_and_the_reverse():
    clock = VirtualClock()
    firmware = PumpFirmware(clock)
    ask(firmware, "irate 6 ml/min")
    ask(firmware, "irun")
    clock.sleep(30.0)
    ask(firmware, "stop")
    ask(firmware, "citime")
    assert (ask(firmware, "itime"), ask(firmware, "ivolume")) == ("0 seconds", "3 ml")
    ask(firmware, "irun")
    clock.sleep(5.0)
    ask(firmware, "civolume")
    assert (ask(firmware, "itime"), ask(firmware, "ivolume")) == ("5 seconds", "0 ul")
    assert ask(firmware, "cttime") == ""
    assert ask(firmware, "ttime") == "Target time not set"


def test_a_ramp_delivers_the_mean_of_its_rates():
    clock = VirtualClock()
    firmware = PumpFirmware(clock)
    assert ask(firmware, "iramp 1 ml/min 3 ml/min 60") == ""
    assert ask(firmware, "iramp") == "1 ml/min to 3 ml/min in 60 seconds"
    ask(firmware, "irun")
    run(firmware, clock, 60.0)
    # a linear ramp from 1 to 3 mL/min over one minute: the mean, 2 mL/min, for 1 min;
    # the staircase lags by one 0.1 s step: 2 mL/min/60 s * 0.1 s * 1 min at most
    volume_ml = float(ask(firmware, "ivolume").split()[0])
    assert volume_ml == pytest.approx(2.0, abs=2 / 60 * 0.1)
    assert ask(firmware, "crate") == "3 ml/min"
    # a plain rate replaces the ramp
    ask(firmware, "irate 1 ml/min")
    assert ask(firmware, "iramp") == "Ramp not set up"


def test_the_address_command_readdresses_the_pump():
    firmware = PumpFirmware(VirtualClock(), strict_address_form="real")
    assert ask(firmware, "address 5") == ""
    assert firmware.execute("ver") is None  # no address: now for pump 0, not this one
    assert firmware.execute("05ver") is None  # digits are taken at address 0 only
    assert ask(firmware, "5:address") == "5"


def test_the_syringe_table_sets_diameter_and_volume():
    firmware = PumpFirmware(VirtualClock())
    assert ask(firmware, "syrm hm1 10 ml") == ""
    assert (ask(firmware, "diameter"), ask(firmware, "svolume")) == ("14.5700 mm", "10 ml")
    assert ask(firmware, "syrm") == "hm1 10 ml"
    assert ask(firmware, "syrm hm1 7 ml").startswith("Argument error: [7 ml]")
    assert ask(firmware, "diameter 20") == ""
    assert ask(firmware, "syrm") == "Custom 10 ml"


def test_an_infuse_only_model_says_so_in_its_metrics():
    firmware = PumpFirmware(VirtualClock(), infuse_only=True)
    assert "Direction          Infuse only" in firmware.execute("metrics").lines
    assert ask(firmware, "wtime") == "Command error: [wtime] /    Unknown command"
