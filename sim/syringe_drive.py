"""The plunger of a simulated syringe pump: volumes as piecewise-linear functions of time.

Between two events (run, stop, rate change, stall, clear) the plunger moves at a
constant rate, so every volume is exact at any clock time without integrating in
steps: the pump's counters, the time it has run, and the net volume it has pushed into
the specimen. The target stop is part of the same function, so the volume stops
exactly at the target however late anyone looks. What stops the plunger for other
reasons (a stall, a stop command) is decided by ``sim.pump`` and applied here.

Counters are what the pump reports and can be cleared; the net volume is physical
(what the specimen holds) and is never cleared.
"""

from __future__ import annotations

import bisect
import math

INFUSE = "i"
WITHDRAW = "w"


class SyringeDrive:
    """One plunger on one clock. Callers pass non-decreasing times ``t_s``."""

    def __init__(self, t_s: float, net_ml: float = 0.0) -> None:
        self.direction = INFUSE
        self.running = False
        self.stalled = False
        self.target_reached = False
        self.target_ml: float | None = None
        self.target_s: float | None = None  # target time: run time in the direction
        self.rate_ml_min = 0.0
        self.t0_s = t_s
        self._counted0_ml = {INFUSE: 0.0, WITHDRAW: 0.0}
        self._run0_s = {INFUSE: 0.0, WITHDRAW: 0.0}
        # (t, net volume) at every event: between them the net volume is linear.
        self._breaks_t_s = [t_s]
        self._breaks_net_ml = [net_ml]

    # ---- reading ----------------------------------------------------------------

    def end_s(self) -> float:
        """When the current motion reaches its target volume or target time, whichever
        comes first (inf with neither or no motion)."""
        if not self.running or (self.target_ml is None and self.target_s is None):
            return math.inf
        end_s = math.inf
        if self.target_ml is not None:
            remaining_ml = self.target_ml - self._counted0_ml[self.direction]
            end_s = self.t0_s + max(remaining_ml, 0.0) / (self.rate_ml_min / 60.0)
        if self.target_s is not None:
            remaining_s = self.target_s - self._run0_s[self.direction]
            end_s = min(end_s, self.t0_s + max(remaining_s, 0.0))
        # on the virtual clock's nanosecond grid, so a stop and a poll due at the same
        # instant coincide exactly instead of by the luck of floating-point rounding
        return round(end_s * 1e9) / 1e9

    def _moving_s(self, t_s: float) -> float:
        if not self.running:
            return 0.0
        return max(0.0, min(t_s, self.end_s()) - self.t0_s)

    def counted_ml(self, direction: str, t_s: float) -> float:
        """The pump's infused (``'i'``) or withdrawn (``'w'``) counter at ``t_s``."""
        moved = self.rate_ml_min / 60.0 * self._moving_s(t_s) if direction == self.direction else 0
        return self._counted0_ml[direction] + moved

    def run_time_s(self, direction: str, t_s: float) -> float:
        moving = self._moving_s(t_s) if direction == self.direction else 0.0
        return self._run0_s[direction] + moving

    def net_ml(self, t_s: float) -> float:
        """Infused minus withdrawn since the start, at any time (past ones included)."""
        if t_s >= self._breaks_t_s[-1]:
            sign = 1.0 if self.direction == INFUSE else -1.0
            moved = sign * self.rate_ml_min / 60.0 * self._moving_s(t_s)
            return self._breaks_net_ml[-1] + moved
        i = bisect.bisect_right(self._breaks_t_s, t_s)
        if i == 0:
            return self._breaks_net_ml[0]
        t_a, t_b = self._breaks_t_s[i - 1], self._breaks_t_s[i]
        v_a, v_b = self._breaks_net_ml[i - 1], self._breaks_net_ml[i]
        return v_a + (v_b - v_a) * (t_s - t_a) / (t_b - t_a)

    # ---- events -----------------------------------------------------------------

    def settle(self, t_s: float) -> bool:
        """Apply the target stop if it happened by ``t_s``; True if it just did."""
        end = self.end_s()
        if t_s < end:
            return False
        self._anchor(end)
        self.running = False
        self.target_reached = True
        return True

    def start(self, direction: str, rate_ml_min: float, t_s: float) -> None:
        self._anchor(t_s)
        self.direction = direction
        self.rate_ml_min = rate_ml_min
        self.running = True
        self.stalled = False
        self.target_reached = False
        self.settle(t_s)  # a target already met ends the run at once

    def change_rate(self, rate_ml_min: float, t_s: float) -> None:
        """A new rate for the current motion (the pump changes speed on the fly)."""
        self._anchor(t_s)
        self.rate_ml_min = rate_ml_min

    def halt(self, t_s: float, *, stalled: bool = False) -> None:
        self._anchor(t_s)
        self.running = False
        self.stalled = stalled
        if not stalled:
            self.target_reached = False

    def set_target(self, target_ml: float | None, t_s: float) -> None:
        """A new target volume (None clears it). Anchoring first means a target below
        the volume already moved ends the motion at the next ``settle``, not in the past."""
        self._anchor(t_s)
        self.target_ml = target_ml

    def set_target_time(self, target_s: float | None, t_s: float) -> None:
        """A new target time (None clears it), against the run time counter."""
        self._anchor(t_s)
        self.target_s = target_s

    def clear(self, direction: str, t_s: float) -> None:
        """Zero one volume counter; the net volume is physical and stays."""
        self._anchor(t_s)
        self._counted0_ml[direction] = 0.0

    def clear_time(self, direction: str, t_s: float) -> None:
        """Zero one run time counter."""
        self._anchor(t_s)
        self._run0_s[direction] = 0.0

    def _anchor(self, t_s: float) -> None:
        """Fold the motion up to ``t_s`` into the counters and start a new segment."""
        net = self.net_ml(t_s)
        # Read everything before writing: each reading depends on the old segment.
        counted = {d: self.counted_ml(d, t_s) for d in (INFUSE, WITHDRAW)}
        run = {d: self.run_time_s(d, t_s) for d in (INFUSE, WITHDRAW)}
        self._counted0_ml, self._run0_s = counted, run
        self.t0_s = t_s
        if t_s > self._breaks_t_s[-1]:
            self._breaks_t_s.append(t_s)
            self._breaks_net_ml.append(net)
        else:
            self._breaks_net_ml[-1] = net
