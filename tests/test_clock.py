"""The shared clock: virtual time must advance at the set speed, never go backwards,
and change speed without a jump."""

import threading
import time

import pytest

from labrig.clock import Clock, RealClock, SimulatedClock


def test_both_clocks_fit_the_contract():
    assert isinstance(RealClock(), Clock)
    assert isinstance(SimulatedClock(), Clock)


def test_simulated_sleep_takes_one_speedth_of_real_time():
    clock = SimulatedClock(speed=100.0)
    real0, virtual0 = time.monotonic(), clock.now()
    clock.sleep(5.0)
    real_s, virtual_s = time.monotonic() - real0, clock.now() - virtual0
    assert virtual_s >= 5.0
    assert real_s < 1.0  # 5 virtual seconds at 100x are 50 ms, with generous slack
    assert virtual_s == pytest.approx(real_s * 100.0, rel=0.05)


def test_simulated_clock_starts_at_its_origin():
    clock = SimulatedClock(speed=1.0, start_s=1234.5)
    assert 1234.5 <= clock.now() < 1235.5


def test_set_speed_keeps_virtual_time_continuous():
    clock = SimulatedClock(speed=1000.0)
    clock.sleep(2.0)
    before = clock.now()
    clock.set_speed(1.0)
    after = clock.now()
    assert 0.0 <= after - before < 0.05


def test_simulated_time_is_monotonic_across_threads():
    clock = SimulatedClock(speed=500.0)
    failures = []

    def reader():
        last = clock.now()
        for _ in range(2000):
            t = clock.now()
            if t < last:
                failures.append((last, t))
            last = t

    threads = [threading.Thread(target=reader) for _ in range(4)]
    for thread in threads:
        thread.start()
    for _ in range(20):
        clock.set_speed(100.0 + 50 * (_ % 3))
    for thread in threads:
        thread.join()
    assert failures == []


@pytest.mark.parametrize("speed", [0.0, -1.0, float("nan")])
def test_a_clock_that_cannot_run_is_refused(speed):
    with pytest.raises(ValueError, match="speed"):
        SimulatedClock(speed=speed)


def test_real_clock_sleeps_for_real():
    clock = RealClock()
    t0 = clock.now()
    clock.sleep(0.02)
    assert clock.now() - t0 >= 0.02
