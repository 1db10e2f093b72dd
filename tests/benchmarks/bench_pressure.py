"""Benchmark: pressure from the real driver on SimDaqTask against the injected truth.

Run: python tests/benchmarks/bench_pressure.py [--write-docs]

NiDaqPressure zeroes for 1 s at atmospheric pressure, then acquires 120 s of simulated
time at 1 kS/s (RSE, ±10 V, 13 bits) while the truth ramps 0 -> 80 kPa, holds and
falls. Errors are the readings minus the truth at each sample's timestamp, for the
sensor's noise on and off, and for a 5.1 V supply assumed to be 5.0 V or measured on ai1.
The quantisation step on ±10 V is 20 V / 2^13 = 2.44 mV = 0.054 kPa at Vs = 5 V.
"""

from __future__ import annotations

import argparse
import sys
import time

import numpy as np

from labrig.cli.performance_doc import add_write_docs_argument, markdown_table, script_doc
from labrig.drivers.ni_daq import NiDaqPressure
from labrig.sim.daq import SimAnalogMultiChannelReader, SimDaqTask
from labrig.time.virtual import VirtualClock

RATE_HZ = 1000.0
RUN_S = 120.0


def truth_kpa(t_s: np.ndarray) -> np.ndarray:
    """Atmospheric for 5 s, a ramp to 80 kPa over 60 s, a 20 s hold, then down again."""
    t = np.asarray(t_s) - 5.0
    return np.clip(np.minimum(80.0 * t / 60.0, 80.0 - 80.0 * (t - 80.0) / 30.0), 0.0, 80.0)


def run(noise_kpa: float, supply_v: float, supply_channel: str | None) -> dict:
    clock = VirtualClock()

    def task_factory():
        return SimDaqTask(clock, truth_kpa, noise_kpa=noise_kpa, supply_v=supply_v, seed=3)

    daq = NiDaqPressure(
        clock,
        supply_channel=supply_channel,
        task_factory=task_factory,
        reader_factory=SimAnalogMultiChannelReader,
    )
    offset_kpa = daq.zero(1.0)
    daq.start(RATE_HZ)
    blocks = []
    started = time.perf_counter()
    read_s = 0.0
    end_s = clock.now() + RUN_S
    while clock.now() < end_s:
        clock.sleep(0.5)
        t0 = time.perf_counter()
        blocks.append(daq.read())
        read_s += time.perf_counter() - t0
    wall_s = time.perf_counter() - started
    daq.stop()
    t = np.concatenate([b.t_s for b in blocks])
    error = np.concatenate([b.pressure_kpa for b in blocks]) - truth_kpa(t)
    return {
        "offset": offset_kpa,
        "bias": float(np.mean(error)),
        "rms": float(np.sqrt(np.mean(error**2))),
        "max": float(np.max(np.abs(error))),
        "block": float(np.max(np.abs(error[: error.size // 100 * 100].reshape(-1, 100).mean(1)))),
        "n": t.size,
        "gaps": int(np.count_nonzero(np.abs(np.diff(t) - 1 / RATE_HZ) > 1e-9)),
        "us_per_sample": read_s / t.size * 1e6,
        "wall_s": wall_s,
    }


def main() -> None:
    parser = argparse.ArgumentParser()
    add_write_docs_argument(parser)
    doc = script_doc(["pressure"], parser.parse_args().write_docs)
    step_kpa = 20.0 / 2**13 / (0.009 * 5.0)  # RSE on a USB-6009: 13 bits
    cases = [
        ("sensor noise 0.05 kPa", 0.05, 5.0, None),
        ("noise off", 0.0, 5.0, None),
        ("noise off, 5.1 V supply assumed to be 5.0 V", 0.0, 5.1, None),
        ("noise off, 5.1 V supply measured on ai1", 0.0, 5.1, "Dev1/ai1"),
    ]
    print(
        f"pressure vs injected truth, {RUN_S:g} s at {RATE_HZ:g} S/s, 0-80 kPa; "
        f"quantisation step {step_kpa:.4f} kPa; sensor offset error 0.8 kPa"
    )
    print(f"python {sys.version.split()[0]}, numpy {np.__version__}")
    header = (
        f"case: {RATE_HZ / 1e3:g} kS/s, {RUN_S:g} s, 0-80 kPa (RSE, step {step_kpa:.3f} kPa)",
        "zero (kPa)",
        "error bias (kPa)",
        "rms",
        "max",
        "max of 100-sample means",
        "samples",
        "gaps",
        "us per sample",
    )
    rows = []
    for name, noise, supply_v, supply_channel in cases:
        r = run(noise, supply_v, supply_channel)
        rows.append(
            (
                name,
                f"{r['offset']:.4f}",
                f"{r['bias']:.4f}",
                f"{r['rms']:.4f}",
                f"{r['max']:.4f}",
                f"{r['block']:.4f}",
                f"{r['n']:,}",
                r["gaps"],
                f"{r['us_per_sample']:.3f}",
            )
        )
    doc.publish("pressure", markdown_table(header, rows, right=set(range(1, 9))))


if __name__ == "__main__":
    main()
