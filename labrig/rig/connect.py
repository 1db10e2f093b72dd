"""What both rigs do the same way once a pump or a DAQ is reachable: a pump set up for
the protocol, the pressure driver built from the rig file's pressure section (with the
load cell when the length is blocked), and whether the protocol needs a technician."""

from __future__ import annotations

from labrig.config.protocol import Protocol, plan
from labrig.config.rig_file import PumpConfig, RigConfig
from labrig.errors import DeviceError, InputError


def set_up_pump(pump, config: PumpConfig, protocol: Protocol) -> None:
    """What a connected pump needs before a run: it can do what the protocol asks, the
    syringe, and the force limit (the hardware backstop, read back)."""
    if not pump.can_withdraw and plan(protocol).withdrawn_ml > 0:
        raise DeviceError(
            f"the pump on {config.port} is infuse-only (its 'metrics' says so) but the "
            "protocol withdraws: use a pump that withdraws, or a protocol without withdraw steps"
        )
    pump.configure_syringe(config.syringe.diameter_mm, config.syringe.volume_ml)
    pump.set_force_limit(config.force_limit_pct)


def pressure_driver(driver_class, clock, config: RigConfig, protocol: Protocol, factories):
    """The pressure driver; with the length blocked, the one that also reads the load
    cell on another input of the same DAQ (the rig file's force section)."""
    kwargs = {} if factories is None else dict(factories)
    p = config.pressure
    if protocol.specimen.length == "blocked":
        from labrig.drivers.ni_daq_force import NiDaqPressureForce

        if config.force is None:
            raise InputError(
                "the protocol blocks the actuator's length (specimen.length: blocked) but "
                "the rig file has no force: section (the load cell's channel and calibration)"
            )
        driver_class = NiDaqPressureForce
        kwargs |= dict(
            force_channel=config.force.channel,
            n_per_v=config.force.n_per_v,
            offset_v=config.force.offset_v,
            capacity_n=config.force.capacity_n,
        )
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


def needs_technician(protocol: Protocol) -> bool:
    """A protocol with prompts or reservoir steps: someone (or the simulated rig's
    technician) takes them."""
    from labrig.config.protocol import PromptStep, ReservoirStep, iter_steps

    return any(isinstance(s, PromptStep | ReservoirStep) for _, s in iter_steps(protocol.steps))
