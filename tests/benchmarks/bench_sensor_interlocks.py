"""Benchmark: how the pressure interlocks see a dead sensor, and how often they trip a
live one. Prints the figures docs/reference/interlocks.md quotes.

Run: python tests/benchmarks/bench_sensor_interlocks.py [--seeds N]

1. The floating wire: the MPX5100's output cut, the USB-6009's open input read through
   the real driver (SimDaqTask's model of the input network), bare and with the rig's
   pull-up; mean and noise in kPa, and the share flagged out of the sensor's band.
2. The stuck-signal check (every sample one number for 0.5 s, at least 50 samples)
   against a quiet sensor: the demo's specimen on the plant, infused to 38 mL, held,
   withdrawn and held, read through the driver, for sensor noise from none to one ADC
   step (0.054 kPa in RSE); the same check judged only while the pump moves, over
   0.5, 2 and 5 s; and labrig's ``PressureFrozen`` (0.3 s, judged only after a second
   whose noise dithered the converter). A run counts once, at its first trip.
3. The run's interlocks (none needs the model): each shipped protocol of water on a
   free length, its first infusion, healthy (false trips) and with the wire cut (the
   pull-up's wiring) at each 0.5 mL (the volume infused from the cut to the trip).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from support.sensor_runs import Leg, acquire, infuse_judged, shipped_infusions

from labrig.config.rig_file import DEFAULT_PULL_UP_KOHM
from labrig.drivers.ni_daq import NiDaqPressure
from labrig.model.segments.catalog import load_segment
from labrig.rig.devices import PressureBlock, PumpState, PumpStatus
from labrig.run.interlocks import PressureFrozen
from labrig.sim.daq import SimAnalogMultiChannelReader, SimDaqTask
from labrig.time.virtual import VirtualClock

LSB_KPA = 20.0 / 2**13 / (0.009 * 5.0)  # one 13-bit RSE step over +-10 V at 45 mV/kPa
NOISES_KPA = (0.0, 0.005, 0.01, 0.02, 0.03, 0.05)
MOVING_WINDOWS_S = (0.5, 2.0, 5.0)


def floating_wire(seeds: int) -> None:
    print("1. floating wire (the open input, read through the driver for 5 s)")
    for pull_up_kohm in (None, DEFAULT_PULL_UP_KOHM):
        wiring = "no pull-up" if pull_up_kohm is None else f"{pull_up_kohm:g} kOhm pull-up"
        for seed in range(seeds):
            clock = VirtualClock()
            tasks = []

            def new_task(seed=seed, clock=clock, tasks=tasks, pull_up_kohm=pull_up_kohm):
                tasks.append(
                    SimDaqTask(
                        clock,
                        lambda t: np.full(len(t), 40.0),
                        seed=seed,
                        pull_up_kohm=pull_up_kohm,
                    )
                )
                return tasks[-1]

            daq = NiDaqPressure(
                clock, task_factory=new_task, reader_factory=SimAnalogMultiChannelReader
            )
            with clock.participate():
                daq.start()
                tasks[-1].fail("vout-floating")
                clock.sleep(5.0)
                block = daq.read()
                daq.stop()
            p = block.pressure_kpa
            means = p[: p.size // 100 * 100].reshape(-1, 100).mean(axis=1)
            print(
                f"   {wiring}, seed {seed}: mean {p.mean():.2f} kPa, noise {p.std():.3f} kPa "
                f"per sample, {means.std():.4f} kPa in 0.1 s means, "
                f"{np.mean(block.out_of_range):.0%} flagged out of band"
            )


class StuckSignal:
    """Every sample one number for ``window_s``: labrig's former stuck-signal interlock
    (``while_moving=False``, 0.5 s) and the candidates judged only while the pump moves."""

    def __init__(self, window_s: float, while_moving: bool = True) -> None:
        self.window_s = window_s
        self.while_moving = while_moving
        self.value = np.nan
        self.since_s: float | None = None

    def check(self, block: PressureBlock, status: PumpStatus) -> str | None:
        moving = not self.while_moving or status.state in (
            PumpState.INFUSING,
            PumpState.WITHDRAWING,
        )
        for t_s, p in zip(block.t_s, block.pressure_kpa, strict=True):
            if not moving or self.since_s is None or p != self.value:
                self.since_s = None if not moving else float(t_s)
                self.value = p
            elif t_s - self.since_s >= self.window_s:
                return "stuck"
        return None


class Frozen:
    """labrig's ``PressureFrozen``, in the shape of the candidates above."""

    def __init__(self) -> None:
        self.interlock = PressureFrozen()

    def check(self, block: PressureBlock, status: PumpStatus) -> str | None:
        return self.interlock.check_pressure(block)


def stuck_signal(seeds: int, rate_ml_min: float, hold_s: float) -> None:
    segments = [load_segment(name) for name in ("B48-T30", "B50-T20")]
    infuse_s = 38.0 / rate_ml_min * 60
    legs = [
        Leg(PumpState.INFUSING, infuse_s, rate_ml_min),
        Leg(PumpState.IDLE, hold_s),
        Leg(PumpState.WITHDRAWING, infuse_s, -rate_ml_min),
        Leg(PumpState.IDLE, hold_s),
    ]
    print(
        f"2. stuck signal: the demo's specimen, 38 mL at {rate_ml_min:g} mL/min, holds of "
        f"{hold_s:g} s; runs tripped of {seeds}"
    )
    for noise_kpa in NOISES_KPA:
        tripped = {
            "always, 0.5 s": 0,
            **{f"moving, {w:g} s": 0 for w in MOVING_WINDOWS_S},
            "frozen, armed by noise": 0,
        }
        states = set()
        for seed in range(seeds):
            checks = {
                "always, 0.5 s": StuckSignal(0.5, while_moving=False),
                **{f"moving, {w:g} s": StuckSignal(w) for w in MOVING_WINDOWS_S},
                "frozen, armed by noise": Frozen(),
            }
            seen: dict[str, str] = {}

            def judge(block, status, checks=checks, seen=seen):
                for name, check in checks.items():
                    if name not in seen and check.check(block, status):
                        seen[name] = status.state.value
                return None

            acquire(segments, legs, judge, seed=seed, noise_kpa=noise_kpa)
            for name, state in seen.items():
                tripped[name] += 1
                states.add(f"{name}: {state}")
        counts = ", ".join(f"{name} {n}" for name, n in tripped.items())
        print(
            f"   noise {noise_kpa:.3f} kPa ({noise_kpa / LSB_KPA:.2f} LSB): {counts}"
            f"{'; while ' + '; '.join(sorted(states)) if states else ''}"
        )


def run_interlocks(seeds: int) -> None:
    print(f"3. the run's interlocks: first infusion of each protocol, {seeds} seeds")
    for name, protocol, step in shipped_infusions():
        false_trips = sum(infuse_judged(protocol, step, seed) is not None for seed in range(seeds))
        latencies, unseen = [], []
        cuts_ml = np.arange(0.0, step.infuse.volume_ml - 1.5, 0.5)
        for cut_ml in cuts_ml:
            tripped_ml = infuse_judged(protocol, step, 0, floating_from_ml=float(cut_ml))
            if tripped_ml is None:
                unseen.append(float(cut_ml))
            else:
                latencies.append(tripped_ml - cut_ml)
        print(
            f"   {name}: false trips {false_trips} of {seeds}; wire cut at 0-"
            f"{cuts_ml[-1]:.1f} mL every 0.5 mL: seen {len(latencies)}, "
            f"after {np.min(latencies):.2f}-{np.max(latencies):.2f} mL (median "
            f"{np.median(latencies):.2f}); not seen in this infusion {len(unseen)}"
        )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=5)
    args = parser.parse_args()
    floating_wire(args.seeds)
    stuck_signal(args.seeds, 40.0, 5.0)
    stuck_signal(args.seeds, 20.0, 10.0)
    run_interlocks(args.seeds)


if __name__ == "__main__":
    main()
