"""The PHD ULTRA driver against the emulator over a real pseudo-terminal: volumes after
timed runs on the simulated clock, target, stall, stop, every injected fault, and the
firmware variants of the reply framing.

Volume tolerances come from what the test can know: a command takes effect somewhere
between the clock readings taken before and after the call, so a volume is bracketed
by the rate times those intervals; the pump's 4-decimal display adds 1e-4 mL.
"""

from __future__ import annotations

import math
import threading
import time

import pytest

from labrig.devices import Pump, PumpState
from labrig.drivers.phd_ultra import PhdUltra
from labrig.drivers.phd_ultra_errors import (
    PumpCommandError,
    PumpDisconnected,
    PumpPortError,
    PumpProtocolError,
    PumpRangeError,
    PumpStalled,
    PumpTimeout,
)
from labrig.sim.pump import PumpEmulator
from labrig.virtual_clock import VirtualClock

TIMEOUT_S = 0.2
DISPLAY_ML = 1e-4  # '1.2345 ml': the pump's counters have 4 decimals


@pytest.fixture
def clock():
    return VirtualClock()


@pytest.fixture
def emulator(clock):
    with PumpEmulator(clock) as emu:
        yield emu


@pytest.fixture
def pump(emulator, clock):
    with PhdUltra.open(emulator.port, clock=clock, timeout_s=TIMEOUT_S) as driver:
        yield driver


def start_run(pump, clock, *, rate_ml_min, direction="infuse", target_ml=None):
    """Clear, set up and start a run; the clock times bracketing the run command."""
    pump.clear_volumes()
    if target_ml is not None:
        pump.set_target_volume(target_ml)
    if direction == "infuse":
        pump.set_infuse_rate(rate_ml_min)
        before_s = clock.now()
        pump.infuse()
    else:
        pump.set_withdraw_rate(rate_ml_min)
        before_s = clock.now()
        pump.withdraw()
    return before_s, clock.now()


def test_the_driver_fits_the_pump_contract_and_connects(pump):
    assert isinstance(pump, Pump)
    assert pump.firmware == "PHD ULTRA 3.0.5"
    assert (pump.syringe.diameter_mm, pump.syringe.volume_ml) == (26.7, 60.0)
    low, high = pump.rate_limits().infuse_ml_min
    assert 0 < low < 1e-3 < 100 < high


def test_volume_after_a_timed_infusion(pump, clock, emulator):
    rate_ml_s = 0.1
    started = start_run(pump, clock, rate_ml_min=rate_ml_s * 60)
    clock.sleep(30.0)
    asked_s = clock.now()
    status = pump.status()
    answered_s = clock.now()
    assert status.state is PumpState.INFUSING
    low = rate_ml_s * (asked_s - started[1]) - DISPLAY_ML
    high = rate_ml_s * (answered_s - started[0]) + DISPLAY_ML
    assert low <= status.infused_ml <= high
    assert low >= 3.0 - DISPLAY_ML  # at least the 30 s slept
    assert status.withdrawn_ml == 0.0
    # Stamped in the middle of its queries: the emulator's own volume then agrees to
    # within the rate times half the status call.
    assert status.infused_ml == pytest.approx(
        emulator.net_volume_ml(status.t_s),
        abs=rate_ml_s * (answered_s - asked_s) / 2 + DISPLAY_ML,
    )


def test_withdrawal_counts_separately_and_pulls_the_net_volume_down(pump, clock, emulator):
    rate_ml_s = 0.05
    started = start_run(pump, clock, rate_ml_min=rate_ml_s * 60, direction="withdraw")
    clock.sleep(20.0)
    pump.stop()
    stopped_s = clock.now()
    status = pump.status()
    assert status.state is PumpState.IDLE
    assert status.infused_ml == 0.0
    assert rate_ml_s * 20.0 - DISPLAY_ML <= status.withdrawn_ml
    assert status.withdrawn_ml <= rate_ml_s * (stopped_s - started[0]) + DISPLAY_ML
    assert emulator.net_volume_ml(clock.now()) == pytest.approx(
        -status.withdrawn_ml, abs=DISPLAY_ML
    )


def test_the_run_stops_at_the_target_volume(pump, clock, emulator):
    start_run(pump, clock, rate_ml_min=30.0, target_ml=1.0)  # 2 s at 0.5 mL/s
    final = pump.wait_until_stopped(poll_s=0.25, timeout_s=60.0)
    assert final.state is PumpState.TARGET_REACHED
    assert final.infused_ml == pytest.approx(1.0, abs=DISPLAY_ML)
    assert emulator.net_volume_ml(clock.now() + 100.0) == pytest.approx(1.0, abs=1e-12)
    # The unsolicited target prompt was absorbed: the next exchanges are in step.
    assert pump.identify() == "PHD ULTRA 3.0.5"
    assert pump.target_volume_ml() == pytest.approx(1.0)
    pump.stop()
    assert pump.status().state is PumpState.IDLE


def test_stop_mid_run_freezes_the_volume(pump, clock, emulator):
    rate_ml_s = 0.1
    started = start_run(pump, clock, rate_ml_min=rate_ml_s * 60)
    clock.sleep(10.0)
    before_stop_s = clock.now()
    pump.stop()
    after_stop_s = clock.now()
    frozen_ml = emulator.net_volume_ml(after_stop_s)
    assert rate_ml_s * (before_stop_s - started[1]) <= frozen_ml
    assert frozen_ml <= rate_ml_s * (after_stop_s - started[0])
    clock.sleep(10.0)
    status = pump.status()
    assert status.state is PumpState.IDLE
    assert status.infused_ml == pytest.approx(frozen_ml, abs=DISPLAY_ML)
    assert emulator.net_volume_ml(clock.now()) == frozen_ml


def test_a_stall_under_load_is_reported_and_cleared_by_stop(clock):
    compliance_kpa_per_ml = 400.0
    checks: list[tuple[float, float]] = []  # (net volume, load) at every load check
    emulator = PumpEmulator(clock, load_pressure_kpa=lambda t_s: load(t_s))

    def load(t_s: float) -> float:
        net_ml = emulator.net_volume_ml(t_s)
        checks.append((net_ml, compliance_kpa_per_ml * net_ml))
        return checks[-1][1]

    with emulator, PhdUltra.open(emulator.port, clock=clock, timeout_s=TIMEOUT_S) as pump:
        start_run(pump, clock, rate_ml_min=6.0)
        with pytest.raises(PumpStalled, match="stalled"):
            pump.wait_until_stopped(poll_s=0.5, timeout_s=120.0)
        status = pump.status()
        assert status.state is PumpState.STALLED
        limit_kpa = emulator.stall_pressure_kpa
        stalled_ml = emulator.net_volume_ml(clock.now())
        # Never before the load passed the limit, and at the first or (if a command
        # raced that check) the second check beyond it.
        assert stalled_ml >= limit_kpa / compliance_kpa_per_ml
        beyond = [net for net, kpa in checks if kpa > limit_kpa]
        assert stalled_ml <= beyond[min(1, len(beyond) - 1)]
        assert status.infused_ml == pytest.approx(stalled_ml, abs=DISPLAY_ML)
        clock.sleep(10.0)
        assert emulator.net_volume_ml(clock.now()) == stalled_ml
        pump.stop()
        assert pump.status().state is PumpState.IDLE


def test_the_pumps_refusals_arrive_typed_with_their_text(pump):
    with pytest.raises(PumpRangeError, match="Out of range"):
        pump.configure_syringe(80.0, 60.0)
    pump.set_infuse_rate(1.0)
    pump.infuse()
    with pytest.raises(PumpCommandError, match="Not allowed while running") as raised:
        pump.configure_syringe(20.0, 30.0)
    assert raised.value.pump_text == "Command error: [diameter] / Not allowed while running"
    pump.stop()
    pump.configure_syringe(14.57, 10.0)
    assert pump.read_syringe().diameter_mm == pytest.approx(14.57)
    # The limits follow the new syringe: as the plunger area, (14.57 / 26.7)^2.
    high = pump.rate_limits().infuse_ml_min[1]
    assert high == pytest.approx(15.3477 * (14.57 / 9.525) ** 2, rel=1e-4)


# ---- faults: the right exception, and the pump left stopped where a stop can be sent --


def test_garbage_in_a_reply(pump, clock, emulator):
    start_run(pump, clock, rate_ml_min=6.0)
    emulator.inject_garbage(8)
    with pytest.raises(PumpProtocolError, match="unreadable reply") as raised:
        pump.status()
    assert "the pump was stopped" in str(raised.value)
    assert emulator.state is PumpState.IDLE


def test_line_noise_between_replies_is_discarded(pump, emulator):
    emulator.inject_garbage(16, into_next_reply=False)
    time.sleep(0.02)
    assert pump.identify() == "PHD ULTRA 3.0.5"


def test_a_dropped_reply(pump, clock, emulator):
    start_run(pump, clock, rate_ml_min=6.0)
    emulator.drop_next_replies(1)
    with pytest.raises(PumpTimeout, match="'status'") as raised:
        pump.status()
    assert "the pump was stopped" in str(raised.value)
    assert emulator.state is PumpState.IDLE
    assert pump.status().state is PumpState.IDLE


def test_the_stop_after_a_dropped_reply_is_dropped_too(pump, clock, emulator):
    start_run(pump, clock, rate_ml_min=6.0)
    emulator.drop_next_replies(2)
    with pytest.raises(PumpTimeout, match="may still be running"):
        pump.volumes_ml()
    pump.stop()  # the line works again: the stop is confirmed
    assert emulator.state is PumpState.IDLE


def test_slow_replies_within_and_beyond_the_timeout(pump, clock, emulator):
    emulator.slow_replies(TIMEOUT_S / 4)
    assert pump.identify() == "PHD ULTRA 3.0.5"
    start_run(pump, clock, rate_ml_min=6.0)
    emulator.slow_replies(TIMEOUT_S * 1.5)
    with pytest.raises(PumpTimeout, match="no reply either"):
        pump.status()
    assert emulator.state is PumpState.IDLE  # the stop got there, only its reply was late
    emulator.slow_replies(0)
    pump.stop()
    # The late replies were discarded, not taken for the answers to later commands.
    assert pump.read_syringe().diameter_mm == 26.7
    assert pump.identify() == "PHD ULTRA 3.0.5"


def test_a_disconnect(pump, clock, emulator):
    start_run(pump, clock, rate_ml_min=6.0)
    emulator.disconnect()
    with pytest.raises(PumpDisconnected, match="may still be running"):
        pump.status()
    with pytest.raises(PumpDisconnected, match="lost earlier"):
        pump.stop()
    # As with a pulled cable, the plunger goes on.
    now_s = clock.now()
    assert emulator.net_volume_ml(now_s + 10.0) > emulator.net_volume_ml(now_s)


def test_an_injected_stall(pump, clock, emulator):
    start_run(pump, clock, rate_ml_min=6.0)
    emulator.stall()
    assert pump.status().state is PumpState.STALLED
    with pytest.raises(PumpStalled):
        pump.wait_until_stopped(poll_s=0.1)
    pump.stop()
    assert emulator.state is PumpState.IDLE


# ---- access and concurrency ----------------------------------------------------------


def test_a_second_program_on_the_same_pump_gets_a_clear_error(pump, emulator):
    with pytest.raises(PumpPortError, match="another program"):
        PhdUltra.open(emulator.port)
    assert pump.identify() == "PHD ULTRA 3.0.5"  # the first one is unaffected


def test_stop_goes_before_the_rest_of_a_status_poll(pump, emulator):
    emulator.slow_replies(0.15)  # status() is three exchanges: 0.45 s
    poller = threading.Thread(target=pump.status)
    poller.start()
    while "00status" not in emulator.received:
        time.sleep(0.001)
    pump.stop()
    poller.join(timeout=5)
    sent = list(emulator.received)
    assert sent[sent.index("00status") :] == ["00status", "00stop", "00ivolume", "00wvolume"]


# ---- firmware variants, end to end ---------------------------------------------------


@pytest.mark.parametrize(
    ("address", "address_form", "emulator_options"),
    [
        (0, "colon", {"target_prompt": "T:"}),
        (0, "none", {"reply_style": "prefixed"}),
        (12, "colon", {"reply_style": "prefixed", "status_prompt_first": True}),
        (7, "digits", {"target_prompt": "T:", "status_prompt_first": True}),
        (3, "digits", {"reply_chunk_bytes": 3, "chunk_gap_s": 0.0005}),
    ],
)
def test_firmware_variants(clock, address, address_form, emulator_options):
    with (
        PumpEmulator(clock, address=address, **emulator_options) as emulator,
        PhdUltra.open(
            emulator.port,
            address=address,
            address_form=address_form,
            clock=clock,
            timeout_s=TIMEOUT_S,
        ) as pump,
    ):
        start_run(pump, clock, rate_ml_min=30.0, target_ml=0.5)
        running = pump.status()
        assert running.state in (PumpState.INFUSING, PumpState.TARGET_REACHED)
        final = pump.wait_until_stopped(poll_s=0.25, timeout_s=60.0)
        assert final.state is PumpState.TARGET_REACHED
        assert final.infused_ml == pytest.approx(0.5, abs=DISPLAY_ML)
        assert math.isclose(pump.infuse_rate_ml_min(), 30.0)
        assert pump.version_details()[1].split()[-1] == str(address)
