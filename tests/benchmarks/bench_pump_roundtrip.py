"""How fast the PHD ULTRA driver talks to the emulator over a pseudo-terminal.

Prints round-trip times (median and 99th percentile) for a one-line query, a status
poll (three exchanges) and the wait of a stop issued while another thread polls
without pause; then a status poll as the simulated rig makes it, on virtual time with
the plunger moving against a load (each command checks the load, and the load check
runs every 0.1 s of rig time), with the CPU time of the process per poll: the figure
that does not depend on how busy the host is. The numbers are the host's and the
emulator's; a real pump at 115200 baud adds about 87 us per byte.

Run: python tests/benchmarks/bench_pump_roundtrip.py [--write-docs]
"""

from __future__ import annotations

import argparse
import statistics
import threading
import time

from labrig.cli.performance_doc import add_write_docs_argument, markdown_table, script_doc
from labrig.drivers.phd_ultra import PhdUltra
from labrig.sim.pump import PumpEmulator
from labrig.time.clock import RealClock
from labrig.time.virtual import VirtualClock

POLL_PERIOD_S = 0.2  # the runner's pump poll period


def timed_ms(call, repeats: int) -> list[float]:
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        call()
        times.append((time.perf_counter() - start) * 1e3)
    return times


def row(name: str, times_ms: list[float], cpu_ms: str = "") -> tuple[str, str, str, str]:
    """An exchange's median and 99th percentile (ms), and its CPU time if measured."""
    p99 = statistics.quantiles(times_ms, n=100)[98]
    return name, f"{statistics.median(times_ms):.3f}", f"{p99:.3f}", cpu_ms


def main() -> None:
    parser = argparse.ArgumentParser()
    add_write_docs_argument(parser)
    doc = script_doc(["pump"], parser.parse_args().write_docs)
    rows = []
    clock = RealClock()
    with PumpEmulator(clock) as emulator, PhdUltra.open(emulator.port, clock=clock) as pump:
        rows.append(row("query (`ver`)", timed_ms(pump.identify, 2000)))
        rows.append(row("`status()`: status, ivolume, wvolume", timed_ms(pump.status, 1000)))
        pump.set_infuse_rate(1.0)
        rate = timed_ms(lambda: pump.set_infuse_rate(1.0), 500)
        rows.append(row("set rate (irate + readback)", rate))

        busy = threading.Event()
        busy.set()

        def poll() -> None:
            while busy.is_set():
                pump.status()

        poller = threading.Thread(target=poll)
        poller.start()
        try:
            rows.append(row("`stop()` while another thread polls", timed_ms(pump.stop, 300)))
        finally:
            busy.clear()
            poller.join()
    rows.append(virtual_time_polls(1500))
    header = ("exchange", "median (ms)", "p99 (ms)", "CPU per poll (ms)")
    doc.publish("pump", markdown_table(header, rows, right={1, 2, 3}))


def virtual_time_polls(n: int) -> tuple[str, str, str, str]:
    """``n`` status polls POLL_PERIOD_S apart on a virtual clock, infusing against a
    load that changes with time (a stand-in for the plant: the pump's cost alone); the
    CPU time is both threads', with the load checks."""
    clock = VirtualClock()
    with (
        clock.participate(),
        PumpEmulator(clock, load_pressure_kpa=lambda t: 10.0 + 1e-3 * t) as emulator,
        PhdUltra.open(emulator.port, clock=clock, timeout_s=10.0) as pump,
    ):
        pump.set_infuse_rate(15.0)
        pump.infuse()
        cpu0 = time.process_time()
        times = []
        for _ in range(n):
            times.append(timed_ms(pump.status, 1)[0])
            clock.sleep(POLL_PERIOD_S)
        cpu_ms = (time.process_time() - cpu0) * 1e3 / n
    return row("`status()` on virtual time, moving", times, f"{cpu_ms:.3f}")


if __name__ == "__main__":
    main()
