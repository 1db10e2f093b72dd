"""How long a stop takes to reach the pump while another exchange waits out its reply
timeout (the emulator drops that reply): the interlocks' stop, written beside the
exchange once the port has been busy for ``STOP_WAIT_S``. Prints the median and the
largest of the trials, in ms from the ``stop()`` call to the emulator having the
command. Run: ``python tests/benchmarks/bench_stop_latency.py [TRIALS]``.
"""

from __future__ import annotations

import contextlib
import statistics
import sys
import threading
import time

from labrig.drivers.phd_ultra import STOP_WAIT_S, PhdUltra
from labrig.drivers.phd_ultra_errors import PumpError
from labrig.sim.pump import PumpEmulator
from labrig.time.clock import RealClock

REPLY_TIMEOUT_S = 2.0


def one_trial(pump: PhdUltra, emulator: PumpEmulator) -> float:
    """Seconds from stop() to the emulator receiving it, during a poll whose reply
    never comes."""
    emulator.drop_next_replies(1)
    sent_before = len(emulator.received)

    def poll() -> None:
        with contextlib.suppress(PumpError):  # given up for the stop: the trial's point
            pump.status()

    poller = threading.Thread(target=poll)
    poller.start()
    while len(emulator.received) == sent_before:
        time.sleep(0.001)
    time.sleep(0.3)  # the reply is overdue
    asked_s = time.monotonic()
    stopper = threading.Thread(target=pump.stop)
    stopper.start()
    while "stop" not in list(emulator.received)[sent_before:]:
        time.sleep(0.0005)
    reached_s = time.monotonic() - asked_s
    stopper.join()
    poller.join()
    return reached_s


def main() -> None:
    trials = int(sys.argv[1]) if len(sys.argv) > 1 else 10
    clock = RealClock()
    with (
        PumpEmulator(clock) as emulator,
        PhdUltra.open(emulator.port, clock=clock, timeout_s=REPLY_TIMEOUT_S) as pump,
    ):
        times_ms = [1e3 * one_trial(pump, emulator) for _ in range(trials)]
    print(
        f"stop during a {REPLY_TIMEOUT_S:g} s timed-out exchange ({trials} trials, port "
        f"waited {1e3 * STOP_WAIT_S:g} ms): median {statistics.median(times_ms):.1f} ms, "
        f"max {max(times_ms):.1f} ms"
    )


if __name__ == "__main__":
    main()
