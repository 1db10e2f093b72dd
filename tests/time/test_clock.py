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


@pytest.mark.parametrize("order", [["c", "a", "b"], ["b", "c", "a"]])
def test_conditions_that_hold_together_wake_in_the_order_of_going_to_sleep(order):
    """Waiters whose conditions come true at one instant run in the order they began
    to wait (whatever order their threads were started in), before the time moves on
    to a sleeper's wake-up."""
    clock = VirtualClock()
    state = {"go": False}
    log = []

    def waiter(name, delay_s):
        def run():
            clock.sleep(delay_s)  # they begin to wait one after another
            clock.wait_for(lambda: state["go"], timeout_s=100.0)
            log.append((clock.now(), name))

        return run

    def sleeper():
        clock.sleep(3.0)
        log.append((clock.now(), "sleeper"))

    with clock.participate():
        threads = [clock.start_thread(sleeper, "sleeper")]
        threads += [  # started a, b, c; waiting in ``order``
            clock.start_thread(waiter(name, 0.1 * order.index(name)), name) for name in "abc"
        ]
        clock.sleep(2.0)
        state["go"] = True
        clock.wait_for(lambda: all(t.done for t in threads), 100.0)
    assert log == [(2.0, name) for name in order] + [(3.0, "sleeper")]


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


def test_signals_landing_in_the_hand_over_are_all_seen_and_leave_the_clock_whole():
    """Python runs a signal handler in the main thread between any two bytecodes,
    which in a paced run or a hold is almost always inside the clock's hand-over. A
    handler that only records (as the run's stop requests do) is run every time and
    leaves the clock whole: 300 signals, each sent once the last was handled, land
    wherever the main thread is while it trades turns with a worker; afterwards time
    still moves exactly as the sleeps say, and the worker ends when asked."""
    import os
    import random
    import signal

    clock = VirtualClock(speed=5.0)
    seen = []
    done = threading.Event()

    def worker():
        while not done.is_set():
            clock.sleep(0.002)

    def interrupter():
        rng = random.Random(1)
        for k in range(1, 301):
            time.sleep(rng.uniform(0, 0.001))
            os.kill(os.getpid(), signal.SIGINT)
            deadline = time.monotonic() + 10.0  # a deadlock guard
            while len(seen) < k and time.monotonic() < deadline:
                time.sleep(0.0001)

    previous = signal.signal(signal.SIGINT, lambda *_: seen.append(clock.now()))
    sender = threading.Thread(target=interrupter, daemon=True)
    try:
        with clock.participate():
            thread = clock.start_thread(worker, "worker")
            sender.start()
            while sender.is_alive():
                clock.sleep(0.002)
            t0 = clock.now()
            clock.sleep(0.5)
            elapsed = clock.now() - t0
            done.set()
            assert clock.wait_for(lambda: thread.done, 10.0)
    finally:
        signal.signal(signal.SIGINT, previous)
    assert len(seen) == 300
    assert elapsed == pytest.approx(0.5, abs=1e-9)


def test_a_signal_another_thread_received_is_handled_while_time_is_held():
    """The kernel may deliver a signal to any thread; Python runs its handler in the
    main thread, once that thread runs. A main thread waiting for its turn while
    another participant holds time still (a serial exchange) still runs it."""
    import signal

    clock = VirtualClock()
    handled = threading.Event()
    held_until_handled = []

    def holder():
        # delivered to this thread, not the main one, while it holds time still
        signal.pthread_kill(threading.get_ident(), signal.SIGINT)
        held_until_handled.append(handled.wait(10.0))  # a deadlock guard

    previous = signal.signal(signal.SIGINT, lambda *_: handled.set())
    try:
        with clock.participate():
            thread = clock.start_thread(holder, "holder")
            clock.wait_for(lambda: thread.done, 60.0)
    finally:
        signal.signal(signal.SIGINT, previous)
    assert held_until_handled == [True]
