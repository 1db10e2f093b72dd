"""How fast the PHD ULTRA driver talks to the emulator over a pseudo-terminal.

Prints round-trip times (median and 99th percentile) for a one-line query, a status
poll (three exchanges) and the wait of a stop issued while another thread polls
without pause; then a status poll as the simulated rig makes it, on virtual time with
the plunger moving against a load (each command checks the load, and the load check
runs every 0.1 s of rig time), with the CPU time of the process per poll: the figure
that does not depend on how busy the host is. Run:
``python tests/benchmarks/bench_pump_roundtrip.py``. The numbers are the host's and the
emulator's; a real pump at 115200 baud adds about 87 us per byte.
"""

from __future__ import annotations

import statistics
import threading
import time

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


def report(name: str, times_ms: list[float]) -> None:
    p99 = statistics.quantiles(times_ms, n=100)[98]
    print(f"{name:<34} median {statistics.median(times_ms):7.3f} ms   p99 {p99:7.3f} ms")


def main() -> None:
    clock = RealClock()
    with PumpEmulator(clock) as emulator, PhdUltra.open(emulator.port, clock=clock) as pump:
        report("query (ver)", timed_ms(pump.identify, 2000))
        report("status() = status+ivolume+wvolume", timed_ms(pump.status, 1000))
        pump.set_infuse_rate(1.0)
        report("set rate (irate + readback)", timed_ms(lambda: pump.set_infuse_rate(1.0), 500))

        busy = threading.Event()
        busy.set()

        def poll() -> None:
            while busy.is_set():
                pump.status()

        poller = threading.Thread(target=poll)
        poller.start()
        try:
            report("stop() while another thread polls", timed_ms(pump.stop, 300))
        finally:
            busy.clear()
            poller.join()
    virtual_time_polls(1500)


def virtual_time_polls(n: int) -> None:
    """``n`` status polls POLL_PERIOD_S apart on a virtual clock, infusing against a
    load that changes with time (a stand-in for the plant: the pump's cost alone)."""
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
    report("status() on virtual time, moving", times)
    print(f"{'':<34} CPU {cpu_ms:7.3f} ms per poll (both threads, with the load checks)")


if __name__ == "__main__":
    main()
