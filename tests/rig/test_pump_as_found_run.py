"""Runs on the simulated rig whose pump was left in a state of its own: infusing when
the run starts, in Quick Start infuse-only, and swapped for another pump behind its
re-found by-id link. Each run says what it found, keeps the pump's identity in its
file, and never sends a stop to a pump that is not its own."""

from __future__ import annotations

import pytest
from support.simrig import SHORT, when_volume_exceeds

from labrig.config.protocol import load_protocol
from labrig.config.rig_file import sim_rig_config
from labrig.recording.run_reader import open_run
from labrig.rig.devices import PumpState
from labrig.rig.simulated import build_simulated_rig
from labrig.run.pump_stop import PUMP_STOP_NOT_CONFIRMED
from labrig.run.runner import Runner

PROTOCOL = SHORT.format(max_pressure_kpa=95, camera_fps=0)


def run(tmp_path, before_connect, inject=None):
    """The short protocol on a simulated rig whose pump ``before_connect`` prepared."""
    protocol_path = tmp_path / "protocol.yaml"
    protocol_path.write_text(PROTOCOL)
    loaded = load_protocol(protocol_path)
    rig = build_simulated_rig(loaded.protocol, sim_rig_config(), before_connect)
    with rig.clock.participate():
        if inject is not None:
            rig.clock.start_thread(lambda: inject(rig), "inject")
        result = Runner(loaded, rig, tmp_path / "run.h5").run()
    return rig, result


def identity_in(path) -> dict[str, str]:
    with open_run(path) as f:
        group = f["entry/pump_identity"]
        return {name: group[name][()].decode() for name in group}


def test_a_run_started_while_the_pump_infuses_stops_it_says_so_and_keeps_its_identity(
    tmp_path, caplog
):
    left = {}

    def infusing(emulator):
        emulator.keypad("irate 1.2 ml/min", "irun")
        # 0.02 mL pushed before labrig connects: little enough for the zeroing to pass
        # (a millilitre inflates the specimen, and the zeroing then refuses the run)
        emulator.clock.sleep(1.0)
        left["net_ml"] = emulator.net_volume_ml(emulator.clock.now())

    _, result = run(tmp_path, infusing)
    assert result.status == "complete", result.reason
    said = [r.getMessage() for r in caplog.records if "labrig stopped it" in r.getMessage()]
    assert len(said) == 1 and said[0].startswith("the pump was infusing at 1.2 mL/min (0.0200 mL")
    identity = identity_in(result.path)
    assert identity["at_connect"] == said[0]
    assert identity["serial_number"] == "EMU00001"
    assert (identity["model"], identity["firmware"]) == ("PHD ULTRA", "3.0.5")
    assert "Serial number: EMU00001" in identity["version"]
    assert left["net_ml"] == pytest.approx(0.02)


def test_a_run_on_a_pump_left_in_quick_start_infuse_withdraws(tmp_path):
    rig, result = run(tmp_path, lambda emulator: emulator.keypad("load qs i"))
    assert result.status == "complete", result.reason
    assert (
        "('load qs iw'): it was in 'Quick Start Infuse'" in identity_in(result.path)["at_connect"]
    )
    withdrawn = [line for line in rig.simulation.emulator.firmware.executed if line == "wrun"]
    assert len(withdrawn) == 2  # both withdraw steps of the protocol ran


def test_another_pump_behind_the_re_found_link_is_not_sent_stop(tmp_path):
    others = []

    def swap(rig):
        if when_volume_exceeds(rig, 5.0):
            emulator = rig.simulation.emulator
            others.append(emulator.another_pump())
            emulator.re_enumerate(0.2, others[0])

    rig, result = run(tmp_path, lambda emulator: None, inject=swap)
    assert result.status == "faulted"
    assert result.reason.startswith(PUMP_STOP_NOT_CONFIRMED)
    assert "not the pump of this run" in result.reason
    assert "serial EMU00002" in result.reason
    assert not result.stop_confirmed
    [other] = others
    assert not any(line.startswith("stop") for line in other.executed)
    assert rig.simulation.emulator.state is PumpState.INFUSING  # this run's pump runs on
