"""The shared clocks. The virtual clock is checked for what the simulated rig relies on:
time moves only when every participant waits, the order at one instant is fixed by
the program alone, waits can be conditions, and a paced timeline records the same
events as an unpaced one."""

import threading
import time

import pytest

from labrig.time.clock import Clock, RealClock, ScaledClock
from labrig.time.virtual import ClockStalled, VirtualClock


def test_both_clocks_fit_the_contract():
    assert isinstance(RealClock(), Clock)
    assert isinstance(VirtualClock(), Clock)


def test_a_lone_sleep_jumps_at_once():
    clock = VirtualClock(start_s=1234.5)
    clock.sleep(3600.0)  # an hour, with nobody else to wait for: no host wait at all
    assert clock.now() == 1234.5 + 3600.0


def test_time_stands_still_while_a_participant_works():
    clock = VirtualClock()
    seen = []

    def worker():
        t0 = clock.now()
        time.sleep(0.05)  # host work: virtual time must not move meanwhile
        seen.append(clock.now() - t0)
        clock.sleep(1.0)
        seen.append(clock.now())

    with clock.participate():
        thread = clock.start_thread(worker, "worker")
        clock.sleep(0.5)
        seen.append(("main", clock.now()))
        assert clock.wait_for(lambda: thread.done, timeout_s=10.0)
    assert seen == [0.0, ("main", 0.5), 1.0]


def test_order_at_one_instant_is_the_order_of_going_to_sleep():
    clock = VirtualClock()
    log = []

    def loop(name, period_s):
        def run():
            for _ in range(5):
                clock.sleep(period_s)
                log.append((clock.now(), name))

        return run

    with clock.participate():
        threads = [clock.start_thread(loop(n, p), n) for n, p in [("a", 0.2), ("b", 0.1)]]
        clock.wait_for(lambda: all(t.done for t in threads), timeout_s=10.0)
    # 'a' went to sleep first each time both are due at the same instant
    expected = sorted(
        [(round(0.2 * k, 9), "a") for k in range(1, 6)]
        + [(round(0.1 * k, 9), "b") for k in range(1, 6)],
        key=lambda e: (e[0], e[1]),
    )
    assert [(round(t, 9), n) for t, n in log] == expected
    # and it is the same however the host schedules the threads
    for _ in range(3):
        again = []
        clock2 = VirtualClock()

        def loop2(name, period_s, clock2=clock2, again=again):
            def run():
                for _ in range(5):
                    time.sleep(0.001 if name == "a" else 0.0)
                    clock2.sleep(period_s)
                    again.append((clock2.now(), name))

            return run

        with clock2.participate():
            ts = [clock2.start_thread(loop2(n, p), n) for n, p in [("a", 0.2), ("b", 0.1)]]
            clock2.wait_for(lambda ts=ts: all(t.done for t in ts), timeout_s=10.0)
        assert again == log


def test_wait_for_wakes_when_the_condition_holds_and_times_out_otherwise():
    clock = VirtualClock()
    state = {"x": 0}

    def producer():
        for _ in range(10):
            clock.sleep(0.25)
            state["x"] += 1

    with clock.participate():
        clock.start_thread(producer, "producer")
        assert clock.wait_for(lambda: state["x"] >= 3, timeout_s=100.0)
        assert clock.now() == 0.75
        assert not clock.wait_for(lambda: state["x"] >= 100, timeout_s=5.0)
        assert clock.now() == 5.75


def test_timers_run_at_their_time_in_order_with_sleepers():
    clock = VirtualClock()
    log = []
    clock.call_at(2.0, lambda: log.append(("timer", clock.now())))
    cancelled = clock.call_at(1.5, lambda: log.append(("cancelled", clock.now())))
    cancelled.cancel()
    clock.call_at(1.0, lambda: log.append(("timer", clock.now())))
    clock.sleep(1.0)  # a timer due at the same instant runs first
    log.append(("sleeper", clock.now()))
    clock.sleep(5.0)
    assert log == [("timer", 1.0), ("sleeper", 1.0), ("timer", 2.0)]
    assert clock.now() == 6.0


def test_speed_paces_the_same_timeline_to_the_wall():
    clock = VirtualClock(speed=20.0)
    real0 = time.monotonic()
    clock.sleep(2.0)  # 0.1 s of wall time at x20
    assert clock.now() == 2.0
    assert time.monotonic() - real0 >= 0.09


def test_a_participant_that_never_comes_back_is_an_error_not_a_hang():
    clock = VirtualClock(stall_timeout_s=0.2)
    errors = []

    def waiter():
        try:
            clock.sleep(1.0)
        except ClockStalled as exc:
            errors.append(str(exc))

    with clock.participate():
        thread = threading.Thread(target=waiter)
        thread.start()
        time.sleep(1.0)  # the main thread blocked outside the clock holds time still
        thread.join(5.0)
    assert errors and "held time still" in errors[0]
    assert clock.now() == 0.0


def test_real_clock_waits_for_real():
    clock = RealClock()
    flag = []
    thread = clock.start_thread(lambda: flag.append(1), "t")
    assert clock.wait_for(lambda: thread.done, timeout_s=5.0)
    assert flag == [1]
    assert not clock.wait_for(lambda: False, timeout_s=0.02)


@pytest.mark.parametrize("speed", [0.0, -1.0])
def test_refused_speeds(speed):
    with pytest.raises(ValueError):
        VirtualClock(speed=speed)


def test_scaled_clock_runs_speed_times_faster_than_the_host():
    clock = ScaledClock(speed=100.0)
    t0 = clock.now()
    clock.sleep(2.0)
    assert clock.now() - t0 >= 2.0
    fired = []
    clock.call_at(clock.now() + 1.0, lambda: fired.append(clock.now()))
    assert clock.wait_for(lambda: bool(fired), timeout_s=100.0)


def test_signals_raising_in_the_main_thread_never_break_the_hand_over():
    """A second Ctrl-C raises in the main thread between any two bytecodes. Raised only
    where the clock says it is ``interruptible`` (as the runner's handler does), 300
    interrupts landing at random in a main thread that trades turns with a worker leave
    the clock whole: both finish, and time is where their sleeps put it."""
    import os
    import random
    import signal

    class Interrupted(Exception):
        pass

    clock = VirtualClock()
    armed = [False]  # raise only inside the test's own try (the runner's is the run)

    def handler(signum, frame):
        if armed[0] and clock.interruptible():
            raise Interrupted

    def worker():
        for _ in range(2000):
            clock.sleep(0.001)

    previous = signal.signal(signal.SIGINT, handler)
    stop = threading.Event()

    def interrupter():
        rng = random.Random(1)
        for _ in range(300):
            if stop.is_set():
                return
            time.sleep(rng.uniform(0, 0.002))
            os.kill(os.getpid(), signal.SIGINT)

    try:
        with clock.participate():
            thread = clock.start_thread(worker, "worker")
            sender = threading.Thread(target=interrupter, daemon=True)
            sender.start()
            done = 0
            while done < 2000:
                try:
                    armed[0] = True
                    clock.sleep(0.001)
                    armed[0] = False
                    done += 1
                except Interrupted:
                    armed[0] = False
            stop.set()
            clock.wait_for(lambda: thread.done, 10.0)
        sender.join(10)
    finally:
        signal.signal(signal.SIGINT, previous)
    assert thread.done
    assert clock.now() == pytest.approx(2.0, abs=0.01)
