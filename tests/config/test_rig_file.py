"""Rig configuration files: the bench example is valid, errors name file/line/key, and
`--sim` swaps every device for the simulated rig but keeps the syringe."""

import pytest

from labrig.config.protocol import load_protocol
from labrig.config.rig_file import load_rig_config
from labrig.errors import InputError

PROTOCOL = """\
name: bench
specimen: {segments: [SI-B46-T20]}
rig: rigs/bench.yaml
limits: {max_pressure_kpa: 95, max_volume_ml: 25}
steps:
  - infuse: {rate_ml_min: 60, volume_ml: 5}
"""


def write_protocol(tmp_path, rig_text):
    (tmp_path / "rigs").mkdir(exist_ok=True)
    (tmp_path / "rigs" / "bench.yaml").write_text(rig_text)
    path = tmp_path / "p.yaml"
    path.write_text(PROTOCOL)
    return load_protocol(path)


def test_the_bench_example_is_valid():
    from pathlib import Path

    root = Path(__file__).parents[2] / "protocols"
    text = (root / "rigs" / "bench.yaml").read_text()
    from labrig.config.rig_file import RigConfig
    from labrig.config.yaml_schema import parse_yaml_model

    config = parse_yaml_model(text, "bench.yaml", RigConfig, what="a rig configuration")
    assert config.pump.port.startswith("/dev/serial/by-id/")  # found again if it re-enumerates
    assert (config.pump.force_limit_pct, config.pump.reply_timeout_s) == (30, 2.0)
    assert config.pressure.supply_channel == "Dev1/ai1"
    assert config.sim is None


def test_a_rig_file_is_found_beside_the_protocol(tmp_path):
    loaded = write_protocol(tmp_path, "pump: {port: /dev/ttyS3, address: 7}\n")
    config = load_rig_config(loaded)
    assert config.pump.port == "/dev/ttyS3" and config.pump.address == 7
    assert config.sim is None and config.camera is None


def test_sim_keeps_the_syringe_and_replaces_the_devices(tmp_path):
    loaded = write_protocol(
        tmp_path, "pump: {port: /dev/ttyS3, syringe: {diameter_mm: 14.5, volume_ml: 10}}\n"
    )
    config = load_rig_config(loaded, force_sim=True)
    assert config.sim is not None
    assert config.pump.syringe.diameter_mm == 14.5
    assert config.pump.port == "emulator"


def test_errors_name_the_rig_file_line_and_key(tmp_path):
    loaded = write_protocol(tmp_path, "pump:\n  port: /dev/ttyS3\n  adress: 7\n")
    with pytest.raises(InputError, match=r"bench\.yaml: line 3: pump\.adress: unknown key"):
        load_rig_config(loaded)
    loaded = write_protocol(tmp_path, "pump: {port: x}\ncamera: {source: 0}\n")
    with pytest.raises(InputError, match="exactly one of mm_per_px and reference_distance_mm"):
        load_rig_config(loaded)


def test_missing_rig_file_and_speed_without_sim(tmp_path):
    path = tmp_path / "p.yaml"
    path.write_text(PROTOCOL)
    loaded = load_protocol(path)
    with pytest.raises(InputError, match="cannot read rig file"):
        load_rig_config(loaded)
    with pytest.raises(InputError, match="--speed applies to the simulated rig only"):
        load_rig_config(loaded, speed=10.0)


def test_pump_settings_default_safely_and_are_checked(tmp_path):
    config = load_rig_config(write_protocol(tmp_path, "pump: {port: /dev/ttyACM0}\n"))
    pump = config.pump
    assert (pump.address_form, pump.reply_timeout_s, pump.force_limit_pct) == ("auto", 2.0, 100)
    assert pump.rated_force_n == pytest.approx(333.6, abs=0.1)  # 75 lbf
    assert not pump.infuse_only
    for bad, allowed in [
        ("force_limit_pct: 0", "greater than or equal to 1"),
        ("force_limit_pct: 150", "less than or equal to 100"),
        ("reply_timeout_s: 0", "greater than 0"),
        ("address_form: colons", "auto"),
    ]:
        loaded = write_protocol(tmp_path, f"pump:\n  port: x\n  {bad}\n")
        with pytest.raises(InputError, match=rf"line 3: pump\.{bad.split(':')[0]}: .*{allowed}"):
            load_rig_config(loaded)


def test_the_pump_is_set_up_from_the_rig_file_and_refuses_what_it_cannot_do(tmp_path):
    from labrig.config.rig_file import PumpConfig
    from labrig.drivers.phd_ultra import PhdUltra
    from labrig.errors import DeviceError
    from labrig.rig.connect import set_up_pump
    from labrig.sim.pump import PumpEmulator
    from labrig.time.virtual import VirtualClock

    clock = VirtualClock()
    infusing = write_protocol(tmp_path, "pump: {port: x}\n").protocol
    (tmp_path / "w.yaml").write_text(PROTOCOL + "  - withdraw: {rate_ml_min: 60, volume_ml: 5}\n")
    withdrawing = load_protocol(tmp_path / "w.yaml").protocol
    config = PumpConfig(port="x", force_limit_pct=30, syringe={"diameter_mm": 27.6})
    with (
        PumpEmulator(clock, infuse_only=True, strict_address_form="none") as emulator,
        PhdUltra.open(emulator.port, clock=clock, timeout_s=0.3) as pump,
    ):
        with pytest.raises(DeviceError, match=r"infuse-only .* but the protocol withdraws"):
            set_up_pump(pump, config, withdrawing)
        assert emulator.firmware._force_pct == 100  # refused before anything was set
        set_up_pump(pump, config, infusing)
        assert emulator.firmware._force_pct == 30
        assert emulator.firmware._diameter_mm == 27.6


def test_the_signal_allowance_is_the_runners_by_default_and_checked(tmp_path):
    from labrig.run.runner import Timing

    base = "pump: {port: /dev/ttyACM0}\n"
    assert load_rig_config(write_protocol(tmp_path, base)).signal_timeout_s == (
        Timing.signal_timeout_s
    )
    longer = load_rig_config(write_protocol(tmp_path, base + "signal_timeout_s: 1.5\n"))
    assert longer.signal_timeout_s == 1.5
    with pytest.raises(InputError, match="signal_timeout_s"):
        load_rig_config(write_protocol(tmp_path, base + "signal_timeout_s: 0\n"))
