"""How fast the PHD ULTRA driver talks to the emulator over a pseudo-terminal.

Prints round-trip times (median and 99th percentile) for a one-line query, a status
poll (three exchanges) and the wait of a stop issued while another thread polls
without pause. Run: ``python tests/bench/bench_pump_roundtrip.py``. The numbers are the
host's and the emulator's; a real pump at 115200 baud adds about 87 us per byte.
"""

from __future__ import annotations

import statistics
import threading
import time

from labrig.clock import RealClock
from labrig.drivers.phd_ultra import PhdUltra
from labrig.sim.pump import PumpEmulator


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


if __name__ == "__main__":
    main()
