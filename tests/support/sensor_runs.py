"""A specimen's pressure read through the real DAQ driver while a known pump schedule
moves it: the simulated plant (segments exchanging fluid through a resistance) behind
SimDaqTask and NiDaqPressure, the pump's status computed from the schedule. Shared by
the interlock tests and the sensor-interlock benchmark."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from labrig.config.protocol import InfuseStep, iter_plan, load_protocol
from labrig.config.rig_file import DEFAULT_PULL_UP_KOHM
from labrig.drivers.ni_daq import NiDaqPressure
from labrig.model.segments.catalog import load_segment
from labrig.rig.devices import PressureBlock, PumpState, PumpStatus
from labrig.run.runner import run_interlocks
from labrig.sim.daq import SimAnalogMultiChannelReader, SimDaqTask
from labrig.sim.plant import Plant
from labrig.time.virtual import VirtualClock

PROTOCOLS = Path(__file__).parents[2] / "protocols"
READ_PERIOD_S = 0.2  # as often as a run reads the DAQ and polls the pump
START_S = 1.0  # the pump starts after this


@dataclass(frozen=True)
class Leg:
    """One stretch of a pump schedule: a state for a time at a rate (mL/min, signed)."""

    state: PumpState
    seconds: float
    rate_ml_min: float = 0.0


def schedule(legs: list[Leg]) -> Callable[[float], tuple[PumpState, float]]:
    """The pump's state and the specimen volume at a time, from ``legs`` after START_S."""

    def at(t_s: float) -> tuple[PumpState, float]:
        t, volume_ml = t_s - START_S, 0.0
        if t < 0:
            return PumpState.IDLE, 0.0
        for leg in legs:
            if t < leg.seconds:
                return leg.state, volume_ml + leg.rate_ml_min / 60 * t
            t -= leg.seconds
            volume_ml += leg.rate_ml_min / 60 * leg.seconds
        return PumpState.IDLE, volume_ml

    return at


def acquire(
    segments: list,
    legs: list[Leg],
    on_reading: Callable[[PressureBlock, PumpStatus], str | None],
    *,
    seed: int,
    noise_kpa: float = 0.05,
    failure: tuple[str, float] | None = None,
    pull_up_kohm: float | None = DEFAULT_PULL_UP_KOHM,
) -> tuple[float, float, str] | None:
    """Read the specimen through the driver every READ_PERIOD_S for the whole schedule,
    handing each block and the pump's status to ``on_reading``; the first reason it
    gives stops it: (time, volume, reason), or None. ``failure``: a SimDaqTask failure
    and the volume infused when it strikes; ``pull_up_kohm``: the sensor's wiring."""
    pump_at = schedule(legs)
    clock = VirtualClock()
    plant = Plant(segments, lambda t: pump_at(t)[1], t0_s=0.0, seed=seed)
    tasks = []

    def new_task() -> SimDaqTask:
        tasks.append(
            SimDaqTask(
                clock,
                plant.pressure_kpa_at,
                seed=seed,
                noise_kpa=noise_kpa,
                pull_up_kohm=pull_up_kohm,
            )
        )
        return tasks[-1]

    daq = NiDaqPressure(clock, task_factory=new_task, reader_factory=SimAnalogMultiChannelReader)
    end_s = START_S + sum(leg.seconds for leg in legs)
    with clock.participate():
        daq.zero(0.5)
        daq.start()
        armed = failure
        try:
            while clock.now() < end_s:
                clock.sleep(READ_PERIOD_S)
                t_s = clock.now()
                state, volume_ml = pump_at(t_s)
                if armed is not None and volume_ml >= armed[1]:
                    tasks[-1].fail(armed[0])
                    armed = None
                status = PumpStatus(t_s, state, max(volume_ml, 0.0), 0.0)
                reason = on_reading(daq.read(), status)
                if reason:
                    return t_s, volume_ml, reason
        finally:
            daq.stop()
    return None


def shipped_infusions() -> list[tuple[str, object, InfuseStep]]:
    """(name, protocol, first infusion) of each shipped protocol of water on a free
    length (the quasi-static plant's)."""
    found = []
    for path in sorted(PROTOCOLS.glob("*.yaml")):
        protocol = load_protocol(path).protocol
        specimen = protocol.specimen
        if specimen.fluid == "water" and specimen.length == "free":
            step = next(s for _, s, _ in iter_plan(protocol.steps) if isinstance(s, InfuseStep))
            found.append((path.stem, protocol, step))
    return found


def infuse_judged(protocol, step: InfuseStep, seed: int, floating_from_ml: float | None = None):
    """The first infusion of ``protocol`` judged by a run's interlocks: the volume at
    the first trip, or None. ``floating_from_ml``: the sensor's output wire is cut there."""
    segments = [load_segment(name) for name in protocol.specimen.segments]
    checks = run_interlocks(protocol)
    rate = step.infuse.rate_ml_min
    legs = [Leg(PumpState.INFUSING, step.infuse.volume_ml / rate * 60, rate)]

    def judge(block: PressureBlock, status: PumpStatus) -> str | None:
        for check in checks:
            reason = check.check_pressure(block) or check.check_pump(status, status.net_volume_ml)
            if reason:
                return reason
        return None

    failure = None if floating_from_ml is None else ("vout-floating", floating_from_ml)
    tripped = acquire(segments, legs, judge, seed=seed, failure=failure)
    return None if tripped is None else tripped[1]
