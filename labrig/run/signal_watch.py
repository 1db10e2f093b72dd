"""Signals that must keep arriving: the pressure samples and the camera's frames.

An interlock on a reading sees only the readings that come; a sensor whose DAQ stalls
or is unplugged, or a camera that stops streaming, sends none, and nothing would trip.
``SignalWatch`` keeps, per signal, the clock time of its newest sample and names the
first signal that has been quiet for longer than its allowance; the runner asks it from
a loop of its own, so a reading loop blocked inside a driver cannot hide its own
silence, when the first watched signal would be overdue (``next_due_s``): a signal that
keeps coming moves that time on, and the loop wakes a few times a second.

A device slow to start (a UVC webcam takes 0.3-1 s to its first frame) is watched only
from its first sample on: ``expect(..., start_s=...)`` takes the first time reported
as the stream's start, and gives the first sample after it ``start_s`` to come.
"""

from __future__ import annotations

import math
import threading

from labrig.time.clock import Clock


class SignalWatch:
    """Per signal: the newest sample's clock time and how long it may be quiet."""

    def __init__(self, clock: Clock) -> None:
        self.clock = clock
        self._lock = threading.Lock()
        self._newest_s: dict[str, float] = {}
        self._allowed_s: dict[str, float] = {}
        # per signal still starting: (the clock time it was expected, its allowance to
        # the first sample, the start time first reported or None)
        self._starting: dict[str, tuple[float, float, float | None]] = {}

    def expect(self, name: str, allowed_s: float, start_s: float | None = None) -> None:
        """Watch ``name`` from now on: its first sample is due within ``allowed_s``;
        with ``start_s``, the first time reported is the stream's start, and the first
        sample after it is due within ``start_s`` of now."""
        now_s = self.clock.now()
        with self._lock:
            self._newest_s[name] = now_s
            self._allowed_s[name] = allowed_s
            if start_s is not None:
                self._starting[name] = (now_s, start_s, None)

    def forget(self) -> None:
        """Stop watching every signal (acquisition paused: nothing is due)."""
        with self._lock:
            self._newest_s.clear()
            self._allowed_s.clear()
            self._starting.clear()

    def arrived(self, name: str, t_s: float) -> None:
        """A sample of ``name`` taken at clock time ``t_s``."""
        with self._lock:
            if name not in self._newest_s:
                return
            if name in self._starting:
                since_s, start_s, first_s = self._starting[name]
                if first_s is None or t_s <= first_s:
                    self._starting[name] = (since_s, start_s, t_s)
                    return
                del self._starting[name]  # started: watched from this sample on
            self._newest_s[name] = max(self._newest_s[name], t_s)

    def quiet_s(self, name: str) -> float:
        """How long ``name`` has sent nothing (0 when it is not watched)."""
        with self._lock:
            newest_s = self._newest_s.get(name)
        return 0.0 if newest_s is None else self.clock.now() - newest_s

    def next_due_s(self) -> float:
        """The earliest clock time at which a watched signal that sends nothing more
        is overdue (infinity when none is watched): the watch need not look before."""
        with self._lock:
            due = [since_s + start_s for since_s, start_s, _ in self._starting.values()]
            due += [
                newest_s + self._allowed_s[name]
                for name, newest_s in self._newest_s.items()
                if name not in self._starting
            ]
        return min(due, default=math.inf)

    def overdue(self) -> str | None:
        """The reason to stop for the first signal quiet beyond its allowance, or None."""
        now_s = self.clock.now()
        with self._lock:
            watched = [(n, t) for n, t in self._newest_s.items() if n not in self._starting]
            starting = list(self._starting.items())
        for name, (since_s, start_s, _) in starting:
            if now_s - since_s >= start_s:
                return (
                    f"{name}: no first sample within {start_s:g} s of starting (since "
                    f"t = {since_s:.2f} s): the device did not start or was disconnected"
                )
        for name, newest_s in watched:
            quiet_s = now_s - newest_s
            if quiet_s >= self._allowed_s[name]:
                return (
                    f"{name}: no sample for {quiet_s:.2f} s (since t = {newest_s:.2f} s; "
                    f"{self._allowed_s[name]:g} s allowed): the device stalled or was "
                    "disconnected"
                )
        return None
