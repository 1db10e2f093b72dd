"""Discrete-event virtual time for the simulated rig, over ordinary threads.

The model is trio's ``MockClock(autojump_threshold=0)`` and SimPy's event queue:
virtual time stands still while any participant of the run works, and when every
participant waits on the clock it jumps straight to the earliest wake-up. Host
latency therefore costs wall time only, never data: a busy machine makes a run slower,
not different.

Participants are threads that take part in time: the ones started with
``start_thread``, and any thread inside ``participate()`` (the runner's main thread).
A thread that is not a participant and calls ``sleep`` or ``wait_for`` joins for the
length of that call, so a test or a fault injector can simply sleep on the clock.

Only one participant runs at a time (it holds the "baton"), and the next one is
chosen by (wake-up time, order of going to sleep): the order of everything that
happens at one instant is a function of the run alone, so the same protocol and seed
give bitwise the same data on any host. While the baton holder is blocked outside the
clock (a serial exchange with the pump emulator, a join), time holds still until it
returns; every such wait has its own host timeout, and ``stall_timeout_s`` turns a
participant that never comes back into an error rather than a hang.

Timers (``call_at``) are the emulators' events (a pump reaching its target volume,
its load check): they run in order with the waiters, in whichever thread hands the
baton on, with time set to their due time.

``speed`` paces the same timeline to the wall clock (``speed=1`` is real time, for
training); it never changes what is recorded, only when. ``stop_pacing`` lets the rest
run as fast as it computes, at once (a stop request: at ``--speed 0.01`` the next
sample may be a minute of wall time away, and the stop must not wait for it).
"""

from __future__ import annotations

import contextlib
import heapq
import itertools
import logging
import threading
import time
from collections.abc import Callable, Iterator

log = logging.getLogger(__name__)

# A participant that waits this long (host seconds) for its turn while another holds
# time still has met a deadlock or a hung device: it raises instead of hanging.
DEFAULT_STALL_TIMEOUT_S = 120.0
# How far the wall may fall behind a paced timeline before pacing restarts from now
# (instead of rushing to catch up after a host stall).
PACING_SLACK_S = 0.25
# How often (host seconds) a participant waiting for its turn wakes to look again.
# Python runs a signal handler only in the main thread and only while it runs: a signal
# the kernel delivered to another thread does not cut the main thread's wait short, so
# without this a Ctrl-C would wait for the main thread's next turn (seconds in a slowly
# paced run, forever while another participant holds time still).
WAKE_S = 0.05


def _to_ns(seconds: float) -> int:
    """Times are whole nanoseconds: a deadline built as start + k periods and an event
    computed as start + duration land on the same instant however the floating-point
    sums round, so identical steps take identical times."""
    return round(seconds * 1e9)


class ClockStalled(RuntimeError):
    """No participant handed time on within the stall timeout."""


class _Member:
    """One participant: its wake-up and the lock it is woken with.

    The turn is handed over by releasing a plain lock the member blocks on (a binary
    semaphore): a ``threading.Event`` costs a Python-level condition variable per
    hand-over, and a 30 fps simulated run hands over tens of thousands of times."""

    __slots__ = ("done", "name", "predicate", "result", "seq", "turn", "wake_ns")

    def __init__(self, name: str) -> None:
        self.name = name
        self.turn = threading.Lock()
        self.turn.acquire()  # released by the dispatcher when it is this member's turn
        self.wake_ns = 0
        self.seq = 0
        self.predicate: Callable[[], bool] | None = None
        self.result = True
        self.done = False


class _VirtualThread:
    """A thread started by ``VirtualClock.start_thread``."""

    def __init__(self, member: _Member, thread: threading.Thread) -> None:
        self._member = member
        self.thread = thread
        self.name = member.name

    @property
    def done(self) -> bool:
        return self._member.done


class _Timer:
    __slots__ = ("callback", "cancelled")

    def __init__(self, callback: Callable[[], None]) -> None:
        self.callback = callback
        self.cancelled = False

    def cancel(self) -> None:
        self.cancelled = True


class VirtualClock:
    """Virtual time that advances only when every participant waits on it."""

    def __init__(
        self,
        start_s: float = 0.0,
        *,
        speed: float | None = None,
        stall_timeout_s: float = DEFAULT_STALL_TIMEOUT_S,
    ) -> None:
        if speed is not None and not speed > 0:
            raise ValueError(f"clock speed must be > 0, got {speed!r}")
        self.speed = speed
        self.stall_timeout_s = float(stall_timeout_s)
        self._now_ns = _to_ns(start_s)
        self._lock = threading.RLock()
        self._seq = itertools.count()
        self._running = 0  # participants running now (normally 0 or 1)
        self._handovers = 0  # counts every dispatch: shows that time is being handed on
        self._waiting: list[_Member] = []
        self._timers: list[tuple[int, int, _Timer]] = []  # (due ns, order, timer)
        self._local = threading.local()
        self._pace_wall0 = time.monotonic()
        self._pace_virtual0 = self._now_ns
        self._unpaced = threading.Event()  # set: pacing has been stopped

    # ---- the Clock contract ----------------------------------------------------------

    def now(self) -> float:
        return self._now_ns / 1e9

    def sleep(self, seconds: float) -> None:
        """Wait ``seconds`` of virtual time (``<= 0``: let the others due now go first)."""
        member = self._member()
        if member is None:
            with self.participate():
                self.sleep(seconds)
            return
        self._wait(member, self._now_ns + max(0, _to_ns(seconds)), None)

    def wait_for(self, predicate: Callable[[], bool], timeout_s: float) -> bool:
        if predicate():
            return True
        if not timeout_s > 0:
            return False
        member = self._member()
        if member is None:
            with self.participate():
                return self.wait_for(predicate, timeout_s)
        return self._wait(member, self._now_ns + _to_ns(timeout_s), predicate)

    def start_thread(self, target: Callable[[], None], name: str) -> _VirtualThread:
        member = _Member(name)
        with self._lock:
            # runnable at once, in order: it joins time before the caller moves on
            self._enqueue(member, self._now_ns, None)
        thread = self._spawn(member, target, name)
        self._dispatch()  # started by a thread outside time: nobody else would wake it
        return _VirtualThread(member, thread)

    def _spawn(self, member: _Member, target: Callable[[], None], name: str) -> threading.Thread:

        def bootstrap() -> None:
            self._local.member = member
            try:
                self._await_turn(member)
                target()
            finally:
                self._leave(member)

        thread = threading.Thread(target=bootstrap, name=name, daemon=True)
        thread.start()
        return thread

    def call_at(self, t_s: float, callback: Callable[[], None]) -> _Timer:
        timer = _Timer(callback)
        with self._lock:
            due_ns = max(_to_ns(t_s), self._now_ns)
            heapq.heappush(self._timers, (due_ns, next(self._seq), timer))
        return timer

    @contextlib.contextmanager
    def participate(self) -> Iterator[None]:
        if self._member() is not None:
            yield  # already taking part: nothing changes
            return
        member = _Member(threading.current_thread().name)
        self._local.member = member
        with self._lock:
            join_now = self._running == 0 and not self._waiting
            if join_now:
                self._running += 1
            else:
                self._enqueue(member, self._now_ns, None)
        if not join_now:
            self._dispatch()  # nobody may be running to hand time on
        try:
            if not join_now:
                self._await_turn(member)
            yield
        finally:
            self._leave(member)

    # ---- scheduling ------------------------------------------------------------------

    def _member(self) -> _Member | None:
        return getattr(self._local, "member", None)

    def _enqueue(self, member: _Member, wake_ns: int, predicate) -> None:
        member.wake_ns = wake_ns
        member.predicate = predicate
        member.seq = next(self._seq)
        member.result = True
        self._waiting.append(member)

    def _wait(self, member: _Member, wake_ns: int, predicate) -> bool:
        with self._lock:
            self._enqueue(member, wake_ns, predicate)
            self._running -= 1
        self._dispatch()
        self._await_turn(member)
        return member.result

    def _await_turn(self, member: _Member) -> None:
        """Block until the dispatcher hands this member the baton."""
        if member.turn.acquire(False):
            return  # handed already (to the thread that dispatched: a third of them)
        try:
            handovers, waited_s = self._handovers, 0.0
            while not member.turn.acquire(timeout=min(WAKE_S, self.stall_timeout_s)):
                waited_s += min(WAKE_S, self.stall_timeout_s)
                if waited_s < self.stall_timeout_s:
                    continue
                if self._handovers == handovers:  # nobody moved at all meanwhile
                    raise ClockStalled(
                        f"virtual clock: {member.name} waited {self.stall_timeout_s:g} s of "
                        f"host time for its turn at t = {self.now():.6f} s while a participant "
                        "held time still (blocked outside the clock)"
                    )
                handovers, waited_s = self._handovers, 0.0
        except BaseException:
            # stalled: go on running, out of turn if need be
            with self._lock:
                dispatched = member not in self._waiting
                if not dispatched:
                    self._waiting.remove(member)
                    self._running += 1
            if dispatched:
                member.turn.acquire()  # the hand-over is on its way: take it now
            raise

    def _leave(self, member: _Member) -> None:
        with self._lock:
            self._running -= 1
            member.done = True
        self._local.member = None
        self._dispatch()

    def _dispatch(self) -> None:
        """Hand the baton to the next participant if nobody runs, running every timer
        due before it. Called by a thread that has just stopped running."""
        while True:
            with self._lock:
                if self._running > 0:
                    return
                member, timer, t_ns = self._next()
                if member is None and timer is None:
                    return  # nothing waits: time stays where it is
                self._running += 1  # the timer's callback, or the woken member
                self._handovers += 1
                self._now_ns = max(self._now_ns, t_ns)
            if self.speed is not None:
                self._pace(t_ns)
            if member is not None:
                member.turn.release()
                return
            try:
                timer.callback()
            except Exception:
                log.exception("virtual clock: timer callback failed at t = %.6f s", t_ns / 1e9)
            finally:
                with self._lock:
                    self._running -= 1

    def _next(self) -> tuple[_Member | None, _Timer | None, int]:
        """The next thing due (under the lock): a waiter whose condition holds now, or
        else the earliest of timers and wake-ups (timers first at equal times). With
        nobody waiting nothing is due: timers alone never move time."""
        # one pass (every dispatch makes it): the waiters are queued in the order they
        # went to sleep (``seq``), so the first whose condition holds is the
        # earliest-queued one, and the first of the earliest wake-ups wins a tie
        member = None
        for m in self._waiting:
            if m.predicate is not None and _holds(m.predicate):
                self._waiting.remove(m)
                m.result = True
                return m, None, self._now_ns
            if member is None or m.wake_ns < member.wake_ns:
                member = m
        while self._timers and self._timers[0][2].cancelled:
            heapq.heappop(self._timers)
        if member is None:
            return None, None, self._now_ns  # time moves only towards a waiting participant
        if self._timers and self._timers[0][0] <= member.wake_ns:
            t_ns, _, timer = heapq.heappop(self._timers)
            return None, timer, t_ns
        self._waiting.remove(member)
        if member.predicate is not None:
            member.result = _holds(member.predicate)
        return member, None, member.wake_ns

    def stop_pacing(self) -> None:
        """From now on, and in a wait for the wall clock now, run unpaced (any thread)."""
        self._unpaced.set()

    def _pace(self, t_ns: int) -> None:
        """With a speed, let the wall clock catch up with virtual time ``t_ns``."""
        if self.speed is None or self._unpaced.is_set():
            return
        with self._lock:
            due = self._pace_wall0 + (t_ns - self._pace_virtual0) / 1e9 / self.speed
            late = time.monotonic() - due
            if late > PACING_SLACK_S:
                self._pace_wall0, self._pace_virtual0 = time.monotonic(), t_ns
                return
        if late < 0:
            self._unpaced.wait(-late)


def _holds(predicate: Callable[[], bool]) -> bool:
    """A waiter's condition; one that raises wakes its waiter, which will see why."""
    try:
        return bool(predicate())
    except Exception:
        return True
