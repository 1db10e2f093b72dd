"""What both rigs do the same way once a pump or a DAQ is reachable: a pump set up for
the protocol, and the pressure driver built from the rig file's pressure section."""

from __future__ import annotations

from labrig.config.protocol import Protocol, plan
from labrig.config.rig_file import PumpConfig, RigConfig
from labrig.errors import DeviceError


def set_up_pump(pump, config: PumpConfig, protocol: Protocol) -> None:
    """What a connected pump needs before a run: it can do what the protocol asks, the
    syringe, and the force limit (the hardware backstop, read back)."""
    if not pump.can_withdraw and plan(protocol).withdrawn_ml > 0:
        raise DeviceError(
            f"the pump on {config.port} is infuse-only (it refused 'wvolume') but the "
            "protocol withdraws: use a pump that withdraws, or a protocol without withdraw steps"
        )
    pump.configure_syringe(config.syringe.diameter_mm, config.syringe.volume_ml)
    pump.set_force_limit(config.force_limit_pct)


def pressure_driver(driver_class, clock, config: RigConfig, protocol: Protocol, factories):
    kwargs = {} if factories is None else factories
    p = config.pressure
    return driver_class(
        clock,
        p.channel,
        terminal=p.terminal,
        min_v=p.min_v,
        max_v=p.max_v,
        supply_channel=p.supply_channel,
        supply_v=p.supply_v,
        rate_hz=protocol.acquisition.pressure_rate_hz,
        **kwargs,
    )
