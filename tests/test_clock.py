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


def test_governor_slows_down_when_a_loop_falls_behind_and_speeds_up_when_all_keep_time():
    from labrig.clock import SpeedGovernor

    clock = SimulatedClock(speed=50.0)
    governor = SpeedGovernor(clock, min_speed=5.0, max_speed=100.0, interval_s=0.0)
    governor.report(interval_s=1.0, period_s=0.5)  # a camera frame skipped
    assert clock.speed == pytest.approx(35.0)
    for _ in range(50):
        governor.report(interval_s=2.0, period_s=0.5)
    assert clock.speed == 5.0 and governor.slowest_speed == 5.0  # never below the floor
    for _ in range(100):
        governor.report(interval_s=0.21, period_s=0.2)  # on time
    assert clock.speed == 100.0  # and never above the ceiling
    governor.report(interval_s=0.26, period_s=0.2)  # a little late: hold the speed
    assert clock.speed == 100.0


def test_governor_judges_by_fractions_not_by_the_worst_report():
    from labrig.clock import SpeedGovernor

    clock = SimulatedClock(speed=20.0)
    governor = SpeedGovernor(clock, interval_s=60.0)
    # 200 reports of the 0.2 s loops: 3 % a little late, 1 % late, one twice late in a
    # loop that buffers (a DAQ): nothing lost, so the clock speeds up
    for k in range(200):
        ratio = 1.2 if k % 33 == 0 else 1.6 if k % 100 == 1 else 1.0
        governor.report(ratio * 0.2, 0.2, late_loses_data=False)
    governor.report(0.4, 0.2, late_loses_data=False)
    governor._last_decision -= 61.0
    governor.report(0.2, 0.2, late_loses_data=False)
    assert clock.speed == pytest.approx(22.0)
    # the same window with one camera frame skipped slows it down
    for _ in range(200):
        governor.report(0.2, 0.2, late_loses_data=False)
    governor.report(1.0, 0.5, late_loses_data=True)
    governor._last_decision -= 61.0
    governor.report(0.2, 0.2, late_loses_data=False)
    assert clock.speed == pytest.approx(22.0 * 0.7)
    # and 6 % late reports slow it down too
    for k in range(100):
        governor.report((1.6 if k < 6 else 1.0) * 0.2, 0.2, late_loses_data=False)
    governor._last_decision -= 61.0
    governor.report(0.2, 0.2, late_loses_data=False)
    assert clock.speed == pytest.approx(22.0 * 0.7 * 0.7)


def test_governor_decides_at_most_once_per_interval():
    from labrig.clock import SpeedGovernor

    clock = SimulatedClock(speed=50.0)
    governor = SpeedGovernor(clock, interval_s=60.0)
    for _ in range(10):
        governor.report(interval_s=5.0, period_s=0.5)
    assert clock.speed == 50.0
