"""The pump as a shared bench leaves it, against the emulator over real
pseudo-terminals: found running, in Quick Start, in a method's pause, with an alarm
on; stops confirmed in every state the manual lists; a pump found again after a lost
USB link stopped only once it proves to be the same one."""

from __future__ import annotations

import time

import pytest

from labrig.drivers.phd_ultra import PhdUltra
from labrig.drivers.phd_ultra_errors import (
    PumpDisconnected,
    PumpModeError,
    PumpNotTheSame,
    PumpTimeout,
)
from labrig.rig.devices import PumpState
from labrig.sim.pump import PumpEmulator
from labrig.time.virtual import VirtualClock

TIMEOUT_S = 0.5


@pytest.fixture
def clock():
    return VirtualClock()


def infusing(emulator, rate_ml_min=6.0):
    """The emulated pump infusing, as another program left it."""
    emulator.keypad(f"irate {rate_ml_min} ml/min", "irun")
    assert emulator.state is PumpState.INFUSING


def standing_after(emulator, clock, seconds=30.0) -> bool:
    """The plunger stands still for ``seconds`` of clock time from now."""
    now_s = clock.now()
    return emulator.net_volume_ml(now_s + seconds) == emulator.net_volume_ml(now_s)


def test_a_pump_found_infusing_is_stopped_at_connect_and_the_operator_told(clock, caplog):
    with PumpEmulator(clock) as emulator:
        infusing(emulator)
        clock.sleep(20.0)  # 2 mL at 6 mL/min
        with PhdUltra.open(emulator.port, clock=clock, timeout_s=TIMEOUT_S) as pump:
            assert emulator.state is PumpState.IDLE
            assert standing_after(emulator, clock)
            [notice] = pump.connect_notices
    assert notice.startswith("the pump was infusing at 6 mL/min (2.0000 mL infused")
    assert "labrig stopped it (stop confirmed by its status)" in notice
    assert notice in caplog.text  # on the operator's screen through the log


def test_looking_at_a_running_pump_leaves_it_running(clock):
    with PumpEmulator(clock) as emulator:
        infusing(emulator)
        with PhdUltra.open(
            emulator.port, clock=clock, timeout_s=TIMEOUT_S, take_control=False
        ) as pump:
            assert pump.status().state is PumpState.INFUSING
            assert pump.connect_notices == []
        assert emulator.state is PumpState.INFUSING
        assert "stop" not in emulator.received


@pytest.mark.parametrize(
    ("options", "loaded"),
    [
        ({"quick_start": "i"}, "iw"),
        ({"quick_start": "w"}, "iw"),
        ({"quick_start": "w", "infuse_only": True}, "i"),
        ({"quick_start": "wi"}, None),
    ],
)
def test_the_quick_start_variant_is_set_to_what_labrig_needs(clock, options, loaded):
    with (
        PumpEmulator(clock, **options) as emulator,
        PhdUltra.open(emulator.port, clock=clock, timeout_s=TIMEOUT_S) as pump,
    ):
        asked = [line for line in emulator.received if line.startswith("load")]
        assert asked == ([] if loaded is None else [f"load qs {loaded}"])
        if pump.can_withdraw:  # the withdraw a Quick Start 'i' pump refused now runs
            pump.set_withdraw_rate(1.0)
            pump.withdraw()
            pump.stop()


def test_a_method_waiting_in_its_pause_is_stopped_and_quick_start_loaded(clock):
    """The 'prime' method: 0.5 mL, a 10 s pause, 0.5 mL. Found in the pause (idle by
    prompt and flags), it would move again; stopped, it does not."""
    with PumpEmulator(clock, method="prime") as emulator:
        emulator.keypad("run")
        clock.sleep(7.0)  # 5 s to push 0.5 mL, then 2 s into the pause
        assert emulator.state is PumpState.IDLE and emulator.firmware.method_running
        with PhdUltra.open(emulator.port, clock=clock, timeout_s=TIMEOUT_S) as pump:
            stopped, loaded = pump.connect_notices
            assert "in a method ('Method prime'), standing" in stopped
            assert "'load qs iw'" in loaded
            assert not emulator.firmware.method_running
            assert standing_after(emulator, clock)
            assert emulator.net_volume_ml(clock.now()) == pytest.approx(0.5)


def test_a_locked_method_is_refused_in_one_line_and_nothing_is_run(clock):
    with (
        PumpEmulator(clock, method="prime", locked=True) as emulator,
        pytest.raises(PumpModeError) as raised,
    ):
        PhdUltra.open(emulator.port, clock=clock, timeout_s=TIMEOUT_S)
    message = str(raised.value)
    assert "\n" not in message
    assert "'Method prime' and refused 'load qs iw': Command error: [load] / Method locked" in (
        message
    )
    assert "on its panel" in message


# ---- a stop, confirmed by what the pump reports, in every state --------------------


def _running(pump, emulator, clock):
    pump.set_infuse_rate(6.0)
    pump.infuse()


def _target(pump, emulator, clock):
    pump.set_target_volume(0.1)
    pump.set_infuse_rate(6.0)
    pump.infuse()
    clock.sleep(2.0)
    assert pump.status().state is PumpState.TARGET_REACHED


def _stalled(pump, emulator, clock):
    _running(pump, emulator, clock)
    emulator.stall()
    assert pump.status().state is PumpState.STALLED


def _method_moving(pump, emulator, clock):
    emulator.keypad("load prime", "run")
    clock.sleep(1.0)


def _method_paused(pump, emulator, clock):
    _method_moving(pump, emulator, clock)
    clock.sleep(6.0)
    assert emulator.state is PumpState.IDLE and emulator.firmware.method_running


def _withdrawing(pump, emulator, clock):
    pump.set_withdraw_rate(3.0)
    pump.withdraw()


STATES = {
    "infusing": (_running, {}),
    "withdrawing": (_withdrawing, {}),
    "target reached": (_target, {"target_prompt": "T*"}),
    "stalled": (_stalled, {}),
    "in a method, moving": (_method_moving, {}),
    "in a method's pause": (_method_paused, {}),
    "infuse-only, running": (_running, {"infuse_only": True}),
    "idle": (lambda pump, emulator, clock: None, {}),
}


@pytest.mark.parametrize("state", STATES)
def test_a_stop_is_confirmed_in_every_state(clock, state):
    bring_to, options = STATES[state]
    with (
        PumpEmulator(clock, **options) as emulator,
        PhdUltra.open(emulator.port, clock=clock, timeout_s=TIMEOUT_S) as pump,
    ):
        bring_to(pump, emulator, clock)
        emulator.received.clear()
        pump.stop()
        assert list(emulator.received)[:3] == ["stop", "status", "status"]
        assert emulator.state is PumpState.IDLE
        assert not emulator.firmware.method_running
        assert standing_after(emulator, clock)


def test_a_slow_confirmation_is_waited_for(clock):
    """Replies that take 0.6 s (a pump redrawing after a target alarm), within the
    default 2 s reply timeout: the stop, and a later one, are confirmed."""
    with (
        PumpEmulator(clock) as emulator,
        PhdUltra.open(emulator.port, clock=clock) as pump,
    ):
        _target(pump, emulator, clock)
        emulator.slow_replies(0.6, ("stop", "status"))
        pump.stop()
        pump.stop()
        assert emulator.state is PumpState.IDLE


def test_after_an_unanswered_stop_the_next_waits_the_full_reply_timeout(clock):
    """A stop whose reply never came leaves the pump 'deaf'; the next stop is still
    awaited as long as any reply (not 0.2 s), so a slow but healthy pump confirms it."""
    with (
        PumpEmulator(clock) as emulator,
        PhdUltra.open(emulator.port, clock=clock, timeout_s=1.0) as pump,
    ):
        _running(pump, emulator, clock)
        emulator.drop_next_replies(1)
        with pytest.raises(PumpTimeout, match="'stop'"):
            pump.stop()
        assert pump._deaf
        emulator.slow_replies(0.6, ("stop", "status"))
        pump.stop()
        assert not pump._deaf


# ---- the pump found again behind its by-id link -------------------------------------


def lost_and_found(tmp_path, clock, another=None, **options):
    """An emulator behind a by-id link, infusing through the driver, whose USB link
    drops and comes back (with ``another`` pump answering, if given); the status poll
    that meets the lost port has failed. Returns (emulator, pump, the other pump)."""
    emulator = PumpEmulator(clock, by_id=tmp_path / "usb-Harvard_PHD_ULTRA-if00", **options)
    emulator.start()
    pump = PhdUltra.open(emulator.port, clock=clock, timeout_s=TIMEOUT_S)
    pump.reconnect_s = 5.0
    pump.clear_volumes()
    _running(pump, emulator, clock)
    clock.sleep(5.0)
    pump.status()
    other = None if another is None else emulator.another_pump(**another)
    emulator.re_enumerate(0.2, other)
    with pytest.raises(PumpDisconnected, match="lost the serial port"):
        pump.status()
    return emulator, pump, other


def test_the_same_pump_found_again_is_stopped(tmp_path, clock):
    emulator, pump, _ = lost_and_found(tmp_path, clock)
    try:
        pump.stop()
        assert emulator.state is PumpState.IDLE
        asked = list(emulator.firmware.executed)[-9:]
        assert asked[:4] == ["ver", "version", "diameter", "svolume"]
        assert asked[-3:] == ["stop", "status", "status"]
    finally:
        pump.close()
        emulator.close()


@pytest.mark.parametrize(
    ("another", "differs"),
    [
        ({}, "serial EMU00002, address 0, not PHD ULTRA 3.0.5, serial EMU00001"),
        # the same serial number (a pump that does not keep one, cloned settings): its
        # syringe and its counters still tell
        ({"serial_number": "EMU00001", "diameter_mm": 14.57}, "syringe 14.57 mm"),
        ({"serial_number": "EMU00001"}, "'ivolume' 0.0000 mL, below the"),
    ],
    ids=["another-serial", "another-syringe", "counters-behind"],
)
def test_another_pump_behind_the_re_found_link_is_not_sent_stop(tmp_path, clock, another, differs):
    emulator, pump, other = lost_and_found(tmp_path, clock, another)
    try:
        with pytest.raises(PumpNotTheSame) as raised:
            pump.stop()
        message = str(raised.value)
        assert "what answers there is not the pump of this run" in message
        assert differs in message
        assert "it was not sent 'stop'" in message and "press Stop on it" in message
        assert "stop" not in other.executed  # the other pump is not touched
        assert emulator.state is PumpState.INFUSING  # this run's pump runs on
        # a later stop looks again and refuses again
        with pytest.raises(PumpNotTheSame):
            pump.stop()
        assert "stop" not in other.executed
    finally:
        pump.close()
        emulator.close()


def test_a_device_that_does_not_answer_as_a_pump_is_not_sent_stop(tmp_path, clock):
    emulator, pump, other = lost_and_found(tmp_path, clock, {"poll_mode": "remote"})
    try:
        started = time.monotonic()
        with pytest.raises(PumpNotTheSame, match="does not answer as a PHD ULTRA"):
            pump.stop()
        assert time.monotonic() - started < 30.0
        assert "stop" not in other.executed
    finally:
        pump.close()
        emulator.close()
