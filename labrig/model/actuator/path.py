"""The quasi-static path of an actuator under volume-controlled inflation and deflation.

This is the algorithm's readable Python form, which ``labrig.model.actuator.compiled_path``
mirrors step for step in one compiled function per actuator (a scan's fast path); a
change here is a change there.

Continuation in pressure along branch combinations. On a stable state every segment has
the common pressure p, so with each segment on one monotone branch of its p(v) the state
is a function of p alone: v_i(p) inverts segment i's branch, v(p) = sum_i v_i(p) and
dv/dp = sum_i 1/k_i. Between events nothing needs computing; the path is followed event
to event:

- a segment reaches the end of its branch (its peak, its valley): it changes branch; if
  it crosses its peak this is a stable transition (the paper's (0, 1));
- a fold: on a combination with one segment past its peak (one k_m < 0), the state is
  stable while sum_i 1/k_i < 0 (see ``labrig.model.actuator.equilibria``); where that sum reaches
  zero, v(p) turns, the state is lost and the actuator snaps at constant volume. The fold
  is a root of sum 1/k_i found to ~1e-11 kPa, so its volume (an extremum of v(p)) is
  exact, not limited by a grid;
- several segments reach branch ends at the same pressure (segments with the same
  L_braid peak at exactly the same pressure, a singular Hessian): every way of going on
  is tried; if stable ways exist, the one with the lowest energy at the same volume is
  taken (lowest segment index on a tie); if none, the state is lost there.

A lost state goes where the overdamped flow between the segments takes it
(``labrig.model.actuator.descent``), started from the fold along the direction the path was
moving (the fold's null vector), then the new state is put on its branch combination by
solving sum_i v_i(p) = v. Deflation runs the same machinery with v decreasing.

The path is a list of ``Piece``s (one combination, a pressure interval) and ``Event``s;
``sample_path`` turns it into arrays for plots and JSON, ``labrig.model.actuator.transitions`` into
the paper's transitions.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Sequence
from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from labrig.errors import InputError
from labrig.model.actuator.curve_tables import (
    EXCESS_VOLUME,
    excess_volume,
    inverse_sum_of,
    profiles_of,
    tables_of,
    volumes_on_branches,
)
from labrig.model.actuator.descent import FLOW_TOL, FlowError, settle, volume_unit_ml
from labrig.model.actuator.equilibria import Actuator, stable_scalar
from labrig.model.actuator.fold_search import AT_PRESSURE, AT_VOLUME, START, at_volume_of, find_fold
from labrig.model.actuator.roots import XTOL, bracketed_root

INFLATE = 1
DEFLATE = -1
# The fold screen computes a state exactly where the screened sum 1/k is within this
# fraction of its terms' magnitudes from 0. At 0.05, 35 of 400 random library actuators
# lost a small snap next to coincident peaks; at 0.2 and up, 2 of 400
# (docs/explanation/actuator-model.md).
SCREEN_MARGIN = 0.2


class PathError(FlowError, InputError):
    """A state of the path could not be resolved: one line naming the segments and the
    volume (exit 2 on the command line; a scan records it for that actuator)."""


def _unresolved(actuator: Actuator, v_ml: float, exc: Exception) -> PathError:
    return PathError(
        f"{' + '.join(actuator.names)}: the model cannot resolve the state near "
        f"v = {v_ml:.4g} mL ({exc}); check the segments' tables (labrig model curve)"
    )


@dataclass(frozen=True)
class State:
    """An equilibrium: every segment on a branch, at one pressure."""

    branches: tuple[int, ...]
    p_kpa: float
    v_i_ml: tuple[float, ...]
    k_i: tuple[float, ...]  # dp_i/dv_i, kPa/mL

    @property
    def v_ml(self) -> float:
        return math.fsum(self.v_i_ml)


@dataclass(frozen=True)
class Piece:
    """A continuous stretch of stable states on one branch combination."""

    branches: tuple[int, ...]
    p_from_kpa: float
    p_to_kpa: float
    v_from_ml: float
    v_to_ml: float
    direction: int  # INFLATE or DEFLATE


@dataclass(frozen=True)
class Event:
    """Where the path changes branch combination: ``snap`` is a jump at constant volume
    (``cause`` "fold" or "coincident"), ``crossing`` a stable change of branch."""

    kind: str
    cause: str
    direction: int
    pre: State
    post: State


@dataclass(frozen=True)
class Path:
    """The path of one actuator: pieces and events in the order they happen (a piece
    on each side of every event)."""

    actuator: Actuator
    timeline: tuple[Piece | Event, ...]

    @property
    def pieces(self) -> tuple[Piece, ...]:
        return tuple(x for x in self.timeline if isinstance(x, Piece))

    @property
    def events(self) -> tuple[Event, ...]:
        return tuple(x for x in self.timeline if isinstance(x, Event))

    @property
    def v_end_ml(self) -> float:
        """Volume at which inflation turned (or ended)."""
        return max(p.v_to_ml for p in self.pieces if p.direction == INFLATE)


def default_end_volume_ml(actuator: Actuator) -> float:
    """The end of inflation when none is given: every segment on its last branch at 1.1
    times the highest extremum pressure of any segment. No transition can happen past
    it (each segment is on a rising branch it never leaves, and every state before a
    transition holds less volume), so the whole story of the actuator is in the path."""
    extrema = [
        float(s.p_kpa[b.last])
        for s in actuator.segments
        for b in s.branches[:-1]  # an extremum ends every branch but the last
    ]
    p_end = (
        1.1 * max(extrema) if extrema else max(float(np.max(s.p_kpa)) for s in actuator.segments)
    )
    return math.fsum(
        kern.volume_on_branch(kern.n_branches - 1, max(p_end, kern.branches[-1].p_lo_kpa))[0]
        for kern in actuator.kernels
    )


def quasi_static_path(
    actuator: Actuator,
    v_end_ml: float | None = None,
    *,
    deflate: bool = False,
    screen_margin: float = SCREEN_MARGIN,
    flow_tol: float = FLOW_TOL,
) -> Path:
    """Inflate from the unpressurised state to ``v_end_ml`` (default:
    ``default_end_volume_ml``), then, if ``deflate``, withdraw back to zero.

    ``screen_margin`` and ``flow_tol`` are the solver's accuracy settings (the fold
    screen's margin, see ``_Tracer._find_fold``, and the flow's local error per step in
    units of the tables' sample spacing, see ``labrig.model.actuator.descent.settle``); the
    defaults are what every command uses, the benchmark varies them."""
    tracer = _Tracer(actuator, screen_margin=screen_margin, flow_tol=flow_tol)
    v_end = default_end_volume_ml(actuator) if v_end_ml is None else float(v_end_ml)
    try:
        start = tracer.at(tuple(0 for _ in range(actuator.n)), 0.0)
        timeline, end = tracer.follow(start, INFLATE, v_end)
        if deflate:
            timeline += tracer.follow(end, DEFLATE, 0.0)[0]
    except (FlowError, ArithmeticError, ValueError) as exc:
        # a root without a bracket, a flow that did not settle: never a traceback
        raise _unresolved(actuator, tracer.v_ml, exc) from exc
    return Path(actuator, tuple(timeline))


class _Tracer:
    """The continuation itself; holds the actuator's scalar kernels."""

    def __init__(
        self,
        actuator: Actuator,
        *,
        max_events: int = 10_000,
        screen_margin: float = SCREEN_MARGIN,
        flow_tol: float = FLOW_TOL,
    ) -> None:
        self.actuator = actuator
        self.screen_margin = screen_margin
        self.flow_tol = flow_tol
        self.kernels = actuator.kernels
        self.n = actuator.n
        self.max_events = max_events
        # the volume scale of the actuator, to which the distances below are tied (an
        # actuator of microlitres behaves like one of millilitres)
        self.unit_ml = volume_unit_ml(self.kernels)
        self.tables = tables_of(self.kernels)
        self.v_ml = 0.0  # the volume of the last state reached (for error messages)

    # --- states on a branch combination ------------------------------------------------
    def at(self, branches: tuple[int, ...], p: float) -> State:
        v, k = volumes_on_branches(self.tables, np.array(branches), p)
        return State(branches, p, tuple(v.tolist()), tuple(k.tolist()))

    def at_volume_of(self, branches: tuple[int, ...], m: int, v_m: float) -> State:
        """The state on ``branches`` where segment m holds v_m (its pressure sets the
        others'): one inversion fewer than ``at``, for scans along m's branch."""
        p, v, k = at_volume_of(self.tables, np.array(branches), m, v_m)
        return State(branches, p, tuple(v.tolist()), tuple(k.tolist()))

    def inverse_sum(self, state: State) -> float:
        """dv/dp = sum_i 1/k_i; a branch end (k = 0) counts as +-inf by its side."""
        return inverse_sum_of(self.tables, np.array(state.branches), np.array(state.k_i))

    def _rising(self, i: int, branch: int) -> bool:
        return self.kernels[i].branches[branch].rising

    # --- the loop ----------------------------------------------------------------------
    def follow(self, state: State, direction: int, v_target: float):
        timeline: list[Piece | Event] = []
        for _ in range(self.max_events):
            self.v_ml = state.v_ml
            b = state.branches
            falling = [i for i in range(self.n) if not self._rising(i, b[i])]
            s_p = direction if not falling else -direction
            limits = [
                self.kernels[i].branches[b[i]].p_hi_kpa
                if s_p > 0
                else self.kernels[i].branches[b[i]].p_lo_kpa
                for i in range(self.n)
            ]
            p_stop = min(limits) if s_p > 0 else max(limits)
            fold = (
                self._find_fold(state, falling[0], p_stop, direction) if len(falling) == 1 else None
            )
            if fold is not None and abs(fold.p_kpa - p_stop) <= 1e-10 * max(1.0, abs(p_stop)):
                # a fold within its root's tolerance of the branch end (sum 1/k turns
                # to +inf only at the end, where a segment's slope is 0): the branch
                # end decides (``_cross``, which also snaps if no way on is stable)
                fold = None
            end = (
                fold
                if fold is not None
                else (self.at(b, p_stop) if math.isfinite(p_stop) else None)
            )
            if end is None or direction * (end.v_ml - v_target) >= 0:
                final = self._reach(state, v_target, end, s_p)
                timeline.append(_piece(state, final, direction))
                return timeline, final
            timeline.append(_piece(state, end, direction))
            if fold is not None:
                event = Event("snap", "fold", direction, fold, self._snap_from_fold(fold, s_p))
            else:
                # extrema at the same pressure to rounding (the library's equal peaks);
                # nearer ones are met one after the other
                tol = 1e-14 * max(1.0, abs(p_stop))
                at_limit = [i for i in range(self.n) if abs(limits[i] - p_stop) <= tol]
                event = self._cross(end, at_limit, s_p, direction)
            if event.kind == "snap" and _touched(timeline):
                # the previous snap ended on a state lost at once (it only touched a
                # fold of another combination, e.g. the mirror state of two identical
                # segments): one snap, from where the first started
                first = timeline[-2]
                del timeline[-2:]
                event = Event("snap", first.cause, direction, first.pre, event.post)
            timeline.append(event)
            state = event.post
        raise FlowError(f"more than {self.max_events} events on one path: {self.actuator.names}")

    def _reach(self, state: State, v_target: float, end: State | None, s_p: int) -> State:
        """The state at v_target on the current combination, between state and end."""
        b = state.branches
        if state.v_ml == v_target:
            return state
        f_start = state.v_ml - v_target
        if end is None:  # an unbounded branch: walk out until the target is passed
            args = (self.tables, np.array(b), v_target)
            step = max(1.0, abs(state.p_kpa))
            p_far = state.p_kpa + s_p * step
            while (excess_volume(p_far, args) > 0) == (f_start > 0):
                step *= 2.0
                p_far = state.p_kpa + s_p * step
            return self.reach_between(b, state.p_kpa, p_far, v_target, f_start)
        return self.reach_between(b, state.p_kpa, end.p_kpa, v_target, f_start, end.v_ml - v_target)

    def reach_between(
        self,
        b: tuple[int, ...],
        p_a: float,
        p_b: float,
        v_target: float,
        f_a: float = math.nan,
        f_b: float = math.nan,
    ) -> State:
        """The state at v_target on combination b at a pressure between p_a and p_b,
        where sum_i v_i - v_target (f_a, f_b if known) changes sign."""
        branches = np.array(b)
        p = bracketed_root(EXCESS_VOLUME, self.tables, branches, v_target, p_a, p_b, f_a, f_b, XTOL)
        reached = self._with_volume(self.at(b, p), v_target)
        if reached is None:
            raise FlowError(f"no equilibrium at v = {v_target:.6g} mL on branches {b}")
        return reached

    # --- folds -------------------------------------------------------------------------
    def _find_fold(self, state: State, m: int, p_stop: float, direction: int) -> State | None:
        """First fold on the way from ``state`` to ``p_stop`` (segment m past its peak).

        A fold is where sum_i 1/k_i(p) reaches 0. Each 1/k_i is smooth between the
        samples of segment i's table and can change fast across a few of them (m's
        near-flat dips; another segment's contact kink, where its slope drops from the
        stiff wall to the soft branch and a small snap appears). So the sum is screened
        at every sample pressure of every segment in the piece, each term interpolated
        linearly in p between its own segment's samples (exact there: the sample's v
        and PCHIP slope); where the screened sum comes near 0 the state is computed
        exactly. Brackets are then refined down to m's sample spacing, so the
        first fold is found, not a later one.
        """
        b = state.branches
        s_start = self.inverse_sum(state)
        if math.isnan(s_start):
            # two segments at branch ends at once (+inf - inf): start where the crossing
            # probed this piece and found it stable (``_cross``: never past the piece)
            step = _probe_kpa(state.p_kpa)
            if math.isfinite(p_stop):
                step = min(step, 0.5 * abs(p_stop - state.p_kpa))
            state = self.at(b, state.p_kpa - direction * step)
            s_start = self.inverse_sum(state)
        if not math.isfinite(p_stop):  # a falling last branch continued linearly
            kern = self.kernels[m]
            p_stop = kern.pressure(kern.v_last + (kern.v_last - kern.v_first))
        kind, p, v_m = find_fold(
            self.tables,
            profiles_of(self.kernels),
            np.array(b),
            m,
            direction,
            self.screen_margin,
            state.p_kpa,
            np.array(state.v_i_ml),
            s_start,
            p_stop,
        )
        if kind == AT_PRESSURE:
            return self.at(b, p)
        if kind == AT_VOLUME:
            return self.at_volume_of(b, m, v_m)
        return state if kind == START else None

    def _snap_from_fold(self, fold: State, s_p: int) -> State:
        """Settle from a fold. The flow starts a distance eta along the fold's null
        vector (u_i = 1/k_i, sum u_i = 0 there), the way the path was going, i.e. on the
        fold's unstable manifold to O(eta^2). At a fold the drive away from it is second
        order in eta, so eta must lift it well above the rounding of the pressures
        (~1e-14 kPa); the further out, the fewer slow steps the flow needs to leave. If
        the flow ends back on the fold's own stretch (eta inside the fold's numerical
        uncertainty), or the snap is shorter than eta and the start passed its end (the
        flow then returns to it, which is fine), other eta are tried. eta is a tenth of
        the actuator's volume unit first (``volume_unit_ml``, 0.01 mL for the library):
        tied to the curves, not to the millilitre, so that a scaled actuator snaps
        alike."""
        u = [s_p / k if k != 0 else 0.0 for k in fold.k_i]
        mean = math.fsum(u) / self.n
        u = [x - mean for x in u]
        scale = 1.0 / max(abs(x) for x in u)
        u = [x * scale for x in u]
        for eta in (0.1 * self.unit_ml, 1e-2 * self.unit_ml, 1e-3 * self.unit_ml, self.unit_ml):
            w0 = [v + eta * x for v, x in zip(fold.v_i_ml, u, strict=True)]
            post = self.polish(settle(self.kernels, w0, tol=self.flow_tol), fold.v_ml)
            # not back on the fold's own stable stretch (the fold is known to ~1e-11
            # kPa; a snap along the same branches can be short: 7e-5 kPa, 5e-4 mL
            # next to the near-flat dips and coincident peaks of the library)
            beyond = post.branches != fold.branches or s_p * (post.p_kpa - fold.p_kpa) > 1e-9 * max(
                1.0, abs(fold.p_kpa)
            )
            if beyond and stable_scalar(post.k_i):
                return self._past_semi_stable(post, fold, eta)
        raise FlowError(
            f"no state to snap to from the fold at v = {fold.v_ml:.6g} mL ({self.actuator.names})"
        )

    def _past_semi_stable(self, post: State, fold: State, eta: float) -> State:
        """Where a snap ends on a fold of another combination (one segment past its
        peak and sum 1/k as near 0 as at the fold it came from: e.g. two identical
        segments, whose states mirror each other), the flow only touches that state,
        and every neighbour on its way leads on. Flow on from it, the way the flow
        came, to a state that is stable with a margin (at most a few times)."""
        zero = max(10.0 * _fold_residual(fold.k_i), 1e-9)
        origin = fold
        for _ in range(8):
            if not _fold_residual(post.k_i) <= zero:
                return post
            u = [1.0 / k for k in post.k_i]
            mean = math.fsum(u) / self.n
            u = [x - mean for x in u]
            came = [a - b for a, b in zip(post.v_i_ml, origin.v_i_ml, strict=True)]
            sign = 1.0 if math.fsum(x * d for x, d in zip(u, came, strict=True)) >= 0 else -1.0
            scale = sign / max(abs(x) for x in u)
            w0 = [v + eta * x * scale for v, x in zip(post.v_i_ml, u, strict=True)]
            settled = settle(self.kernels, w0, tol=self.flow_tol)
            origin, post = post, self.polish(settled, post.v_ml)
        return post

    def polish(self, w: Sequence[float], v: float, near_ml: float = 0.0) -> State:
        """The equilibrium at total volume v on the branch combination of volumes w
        (settled by the flow to ~1e-9 kPa). A flow that ends on an extremum of a curve
        (a valley next to a near-flat dip, a peak) may be a rounding error on the wrong
        side of it, or ``near_ml`` from it if the flow ran at another volume, so the
        combinations with such segments on the neighbouring branch are tried next."""
        found = []
        for b in self._combinations_near(w, near_ml):
            state = self._equilibrium_on(b, w, v)
            if state is not None and stable_scalar(state.k_i):
                return state
            if state is not None:
                found.append(state)
        if found:  # no stable one: the caller decides what an unstable end means
            return found[0]
        b = tuple(kern.branch_of(x) for kern, x in zip(self.kernels, w, strict=True))
        raise FlowError(f"no equilibrium at v = {v:.6g} mL on branches {b}")

    def _combinations_near(self, w: Sequence[float], near_ml: float) -> list[tuple[int, ...]]:
        options = []
        for kern, x in zip(self.kernels, w, strict=True):
            b = kern.branch_of(x)
            near = [b]
            tol = max(1e-6 * kern.spacing_near(x), near_ml)
            for other in (b - 1, b + 1):
                if 0 <= other < kern.n_branches:
                    branch = kern.branches[other]
                    if branch.v_lo_ml - tol <= x <= branch.v_hi_ml + tol:
                        near.append(other)
            options.append(near)
        combos = list(itertools.product(*options))
        first = combos[0]
        return sorted(combos, key=lambda c: sum(x != y for x, y in zip(c, first, strict=True)))

    def _equilibrium_on(self, b: tuple[int, ...], w: Sequence[float], v: float) -> State | None:
        """Newton on sum_i v_i(p) = v on combination b, falling back to the nearest
        bracketed root if Newton leaves the combination's pressure range; None if the
        combination holds no equilibrium at v."""
        p_lo = max(kern.branches[i].p_lo_kpa for kern, i in zip(self.kernels, b, strict=True))
        p_hi = min(kern.branches[i].p_hi_kpa for kern, i in zip(self.kernels, b, strict=True))
        if p_lo > p_hi:
            return None
        mean_p = (
            math.fsum(kern.pressure(x) for kern, x in zip(self.kernels, w, strict=True)) / self.n
        )
        p0 = p = min(max(mean_p, p_lo), p_hi)
        for _ in range(30):
            state = self.at(b, p)
            excess = state.v_ml - v
            if abs(excess) <= 1e-12 * max(1.0, v):
                return state
            slope = self.inverse_sum(state)
            p = p - excess / slope if math.isfinite(slope) and slope != 0 else math.nan
            if not p_lo <= p <= p_hi:
                break

        args = (self.tables, np.array(b), v)

        def excess_at(q: float) -> float:
            return excess_volume(q, args)

        f0 = excess_at(p0)
        width = 1e-6 * max(1.0, abs(p0))
        while True:
            for q in (max(p0 - width, p_lo), min(p0 + width, p_hi)):
                f = excess_at(q)
                if (f > 0) != (f0 > 0):
                    root = bracketed_root(EXCESS_VOLUME, *args, p0, q, f0, f, XTOL)
                    return self._with_volume(self.at(b, root), v)
            if p0 - width <= p_lo and p0 + width >= p_hi:
                return None
            width *= 4.0

    def _with_volume(self, state: State, v: float) -> State | None:
        """``state``, a root in p of sum_i v_i(p) = v, with the volume made exact.

        Where a segment's p(v) is flat (a plateau) or so nearly flat that a change of p
        at rounding level moves its volume visibly, sum_i v_i(p) jumps at that pressure
        and the root lands on the jump. The segment that can take the difference on its
        branch with the least change of pressure (no more than rounding) then takes it:
        the state is an equilibrium at the right volume. None if no segment can."""
        residual = v - state.v_ml
        if abs(residual) <= 1e-9 * max(1.0, abs(v)):
            return state
        best = None
        for i, (kern, b) in enumerate(zip(self.kernels, state.branches, strict=True)):
            branch = kern.branches[b]
            v_i = state.v_i_ml[i] + residual
            if not branch.v_lo_ml <= v_i <= branch.v_hi_ml:
                continue
            p_i, k_i = kern.pressure_and_slope(v_i)
            change = abs(p_i - state.p_kpa)
            if best is None or change < best[0]:
                k_i = max(k_i, 0.0) if branch.rising else min(k_i, 0.0)
                best = (change, i, v_i, k_i)
        if best is None or best[0] > 1e-9 * max(1.0, abs(state.p_kpa)):
            return None
        _, i, v_i, k_i = best
        volumes, slopes = list(state.v_i_ml), list(state.k_i)
        volumes[i], slopes[i] = v_i, k_i
        return State(state.branches, state.p_kpa, tuple(volumes), tuple(slopes))

    # --- branch ends -------------------------------------------------------------------
    def _switched(self, i: int, branch: int, s_p: int) -> int | None:
        """The branch segment i enters when it reaches the end of ``branch`` moving in
        pressure direction s_p (a rising branch's top leads on, its bottom back), or
        None past either end of the curve."""
        forward = self._rising(i, branch) == (s_p > 0)
        new = branch + (1 if forward else -1)
        return new if 0 <= new < self.kernels[i].n_branches else None

    def _cross(self, end: State, at_limit: list[int], s_p: int, direction: int) -> Event:
        """Change branch where segments reach the ends of theirs (see module docstring).

        Each segment at its limit either changes branch or stays and turns back. Every
        way on turns the pressure back (both sides of an extremum lie on the same side
        in pressure), so a way on is a combination with at most one falling branch whose
        pressure direction is reversed, stable just past the point, with v moving on.
        """
        b = end.branches
        delta = _probe_kpa(end.p_kpa)
        candidates = []
        for size in range(1, len(at_limit) + 1):
            for subset in itertools.combinations(at_limit, size):
                switched = [self._switched(i, b[i], s_p) for i in subset]
                if None in switched:
                    continue
                new = list(b)
                for i, branch in zip(subset, switched, strict=True):
                    new[i] = branch
                new = tuple(new)
                falling = sum(not self._rising(i, new[i]) for i in range(self.n))
                if falling > 1 or (direction if falling == 0 else -direction) != -s_p:
                    continue
                # within the pressure range of every branch (a near-flat dip's falling
                # branch can span less than the default probe distance)
                room = min(
                    (kern.branches[bi].p_hi_kpa - end.p_kpa)
                    if s_p < 0
                    else (end.p_kpa - kern.branches[bi].p_lo_kpa)
                    for kern, bi in zip(self.kernels, new, strict=True)
                )
                if not room > 0:
                    continue
                probe = self.at(new, end.p_kpa - s_p * min(delta, 0.5 * room))
                moved = direction * (probe.v_ml - end.v_ml)
                if stable_scalar(probe.k_i) and moved > 0:
                    candidates.append((moved, subset, new))
        if candidates:
            _, _, new = min(candidates)
            cause = "branch end" if len(at_limit) == 1 else "coincident branch ends"
            return Event("crossing", cause, direction, end, _rebranch(end, new, at_limit))
        if all(self._switched(i, b[i], s_p) is None for i in at_limit):
            names = ", ".join(self.kernels[i].name for i in at_limit)
            raise FlowError(f"the path runs past the end of the curve of {names}")
        # No stable way on: the state is lost here. Feed a little more volume into the
        # segments at their limits and let the flow decide; then back to this volume.
        # Past an extremum the pressures differ only to second order in the volume, so
        # the extra volume must be large enough to lift that above rounding; where
        # extrema crowd within rounding of each other (near-flat dips next to a common
        # peak), a larger one is tried.
        for extra in (1e-2 * self.unit_ml, 1e-1 * self.unit_ml):
            w0 = list(end.v_i_ml)
            for i in at_limit:
                w0[i] += direction * extra / len(at_limit)
            settled = settle(self.kernels, w0, tol=self.flow_tol)
            post = self.polish(settled, end.v_ml, near_ml=2.0 * extra)
            if stable_scalar(post.k_i):
                break
        else:
            raise FlowError(
                f"the flow from coincident branch ends at v = {end.v_ml:.6g} mL did not settle"
            )
        return Event("snap", "coincident", direction, end, post)


def _fold_residual(k: Sequence[float]) -> float:
    """|sum 1/k| relative to its terms where exactly one segment is past its peak (0 at
    a fold); inf for any other state (not a fold)."""
    if sum(x < 0 for x in k) != 1 or 0.0 in k:
        return math.inf
    inverse = [1.0 / x for x in k]
    return abs(math.fsum(inverse)) / math.fsum(abs(x) for x in inverse)


def _probe_kpa(p_kpa: float) -> float:
    """How far past a point where segments reach branch ends the ways on are tried:
    far enough that the slopes there are not rounding, close enough to be asymptotic."""
    return 1e-7 * max(1.0, abs(p_kpa))


def _rebranch(state: State, branches: tuple[int, ...], at_limit: Sequence[int]) -> State:
    """The same point on other branches. The segments at their branch ends sit on an
    extremum of their curve, where the slope is exactly 0 (PCHIP puts it there); their
    slopes are set so, whatever rounding gave on the branch they arrived on."""
    k = tuple(0.0 if i in at_limit else x for i, x in enumerate(state.k_i))
    return State(branches, state.p_kpa, state.v_i_ml, k)


def _touched(timeline: list[Piece | Event]) -> bool:
    """The timeline ends with a snap and then a piece too short to be a state of its own
    (within the solver's rounding of the snap's end)."""
    if len(timeline) < 2:
        return False
    snap, piece = timeline[-2], timeline[-1]
    if not (isinstance(snap, Event) and snap.kind == "snap" and isinstance(piece, Piece)):
        return False
    size = max(abs(piece.v_from_ml), abs(piece.v_to_ml))
    return abs(piece.v_to_ml - piece.v_from_ml) <= 1e-10 * size


def _piece(start: State, end: State, direction: int) -> Piece:
    return Piece(start.branches, start.p_kpa, end.p_kpa, start.v_ml, end.v_ml, direction)


@lru_cache(maxsize=8)
def _default_tracer(actuator: Actuator) -> _Tracer:
    """A tracer with the default settings, shared by the lookups on one actuator's path
    (``transitions`` makes a few per path)."""
    return _Tracer(actuator)


def state_on_piece(actuator: Actuator, piece: Piece, v_ml: float) -> State:
    """The path's state at volume ``v_ml`` on ``piece``, clamped to the piece's ends."""
    tracer = _default_tracer(actuator)
    lo, hi = sorted((piece.v_from_ml, piece.v_to_ml))
    v = min(max(v_ml, lo), hi)
    if v == piece.v_from_ml:
        return tracer.at(piece.branches, piece.p_from_kpa)
    if v == piece.v_to_ml:
        return tracer.at(piece.branches, piece.p_to_kpa)
    try:
        return tracer.reach_between(piece.branches, piece.p_from_kpa, piece.p_to_kpa, v)
    except (FlowError, ArithmeticError, ValueError) as exc:
        # no sign change of the volume between the piece's ends: v is within rounding of
        # one end (the ends' volumes were found at other pressures); within the tables'
        # resolution (their volume unit) that end is the state
        ends = [tracer.at(piece.branches, p) for p in (piece.p_from_kpa, piece.p_to_kpa)]
        nearest = min(ends, key=lambda state: abs(state.v_ml - v))
        if abs(nearest.v_ml - v) <= tracer.unit_ml:
            return nearest
        raise _unresolved(actuator, v, exc) from exc


@dataclass(frozen=True)
class SampledPath:
    """The path as arrays (for plots and JSON); a snap appears as two consecutive
    points at the same volume."""

    v_ml: np.ndarray  # (N,)
    p_kpa: np.ndarray  # (N,)
    l_mm: np.ndarray  # (N,)
    v_i_ml: np.ndarray  # (n, N)
    direction: np.ndarray  # (N,) INFLATE or DEFLATE


def sample_path(path: Path, dv_ml: float = 0.05) -> SampledPath:
    """Points along every piece, about ``dv_ml`` apart in volume. They are spaced like
    (1 - cos) in pressure, denser towards the piece's ends: where a piece starts or
    ends at a segment's extremum, v varies like the square root of p, and this spacing
    makes the points about even in volume there too."""
    segments = path.actuator.segments
    chunks = []
    for piece in path.pieces:
        count = math.ceil(1.6 * abs(piece.v_to_ml - piece.v_from_ml) / dv_ml) + 16
        s = 0.5 * (1.0 - np.cos(np.linspace(0.0, math.pi, count)))
        p = piece.p_from_kpa + (piece.p_to_kpa - piece.p_from_kpa) * s
        p = np.clip(p, *sorted((piece.p_from_kpa, piece.p_to_kpa)))  # no rounding past an end
        v_i = np.array(
            [seg.volume_on_branch(b, p)[0] for seg, b in zip(segments, piece.branches, strict=True)]
        )
        chunks.append((p, v_i, np.full(count, piece.direction)))
    p = np.concatenate([c[0] for c in chunks])
    v_i = np.concatenate([c[1] for c in chunks], axis=1)
    direction = np.concatenate([c[2] for c in chunks])
    # consecutive pieces share their end point (also where inflation turns into
    # deflation), except across a snap
    keep = np.ones(len(p), dtype=bool)
    keep[1:] = np.any(np.abs(np.diff(v_i, axis=1)) > 1e-12, axis=0)
    p, v_i, direction = p[keep], v_i[:, keep], direction[keep]
    l_mm = sum(seg.length_mm(v) for seg, v in zip(segments, v_i, strict=True))
    return SampledPath(v_i.sum(axis=0), p, np.asarray(l_mm), v_i, direction)
