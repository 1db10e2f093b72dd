"""The simulated specimen: n segments filled by the pump, exchanging fluid.

Each segment hangs off a common inlet manifold through a small flow resistance R
(kPa s/mL, equal up to a seeded 0.1 % spread); the manifold itself holds no volume. With
the pump supplying Q and equal resistances, the flow into segment i is
Q/n + (mean_j p_j - p_i)/R, so the total volume always equals the pump's and, at a
snap-through, fluid flows from the higher- to the lower-pressure segments over a finite
time — the overdamped energy descent the model uses to decide where a snap ends. In the
slow limit (Q R << the pressure differences that matter) the plant follows the model's
quasi-static path. The sensor sits on the manifold and reads mean p + R Q / n (changed
by the specimen's ``behaviour``, ``labrig.sim.specimen``, when it has one).

The default R = 0.1 kPa s/mL is calibrated on the paper's water figure (a snap takes
about 1 s, Movie S7): for B48-T30 + B50-T20 at 20 mL/min the (2, 1) snap moves 9.8 mL
in 0.83 s (10-90 % of the internal flow) and starts 0.45 mL after the model's fold (the
bottleneck delay of a fold crossed at a finite rate); R = 1 would take 12 s and start
3 mL late.

Time steps are backward Euler with Newton iterations (the stiffening wall makes the
system stiff) and an adaptive step. Each step's local error, estimated from how much
the segments' flows changed over it, stays below ``step_error_ml``, the sensor
pressure's bend away from the straight line the history draws between the step's ends
below ``step_bend_kpa``, and the next step grows or shrinks with the square root of the
margin (both errors go with the step squared); no step moves more than
``max_step_volume_ml``, lasts longer than ``max_step_s``, or outruns the rate at which
an unstable exchange between the segments grows (``growth_rate``): a backward Euler
step longer than 1/rate would damp an unstable state into a false equilibrium. At rest
and at a steady flow the flows hardly change and steps are long; through a snap they
are fractions of a millisecond. Against a fine reference integration
(tests/sim/test_plant.py) the sensor's pressure stays within 0.1 kPa away from the
snaps and a snap starts within a few milliseconds of the reference's; one segment reads
its curve within 0.03 kPa.

The plant is advanced lazily to the latest time anyone asks about and keeps a history,
so the DAQ can ask for 1,000 sample times per second and the camera for a frame time in
any order within ``history_s``. Thread-safe.
"""

from __future__ import annotations

import bisect
import math
import threading
from collections.abc import Callable, Sequence
from operator import mul, sub

import numpy as np

from labrig.model.segments.curve import SegmentCurve
from labrig.sim.specimen import SpecimenBehaviour


class ScalarCurve:
    """p(v), dp/dv and l(v) of one segment for one volume at a time, in plain floats.

    The same PCHIP pieces as SegmentCurve (read from the cache with its tables, without
    scipy), evaluated with bisect and Horner's rule: the plant takes tens of thousands
    of tiny steps per run, and numpy's per-call overhead would dominate them.
    """

    def __init__(self, curve: SegmentCurve) -> None:
        pieces = curve.pieces
        self.x = pieces.x.tolist()
        # the knots between the intervals: bisecting them gives a volume's interval,
        # the first one below the table and the last one above it
        self._inner_knots = self.x[1:-1]
        self.p_coef = pieces.p_coefficients.T.tolist()
        self.l_coef = pieces.l_coefficients.T.tolist()
        self.v_end = self.x[-1]
        self.p_end = float(curve.p_kpa[-1])
        self.slope_end = pieces.end_slope_kpa_per_ml
        self.l_end = float(curve.l_mm[-1])

    def pressure_and_slope(self, v: float) -> tuple[float, float]:
        if v > self.v_end:
            return self.p_end + self.slope_end * (v - self.v_end), self.slope_end
        i = bisect.bisect_right(self._inner_knots, v)
        a, b, c, d = self.p_coef[i]
        h = v - self.x[i]
        return ((a * h + b) * h + c) * h + d, (3 * a * h + 2 * b) * h + c

    def length(self, v: float) -> float:
        if v > self.v_end:
            return self.l_end
        i = bisect.bisect_right(self._inner_knots, v)
        a, b, c, d = self.l_coef[i]
        h = v - self.x[i]
        return ((a * h + b) * h + c) * h + d

    def length_slope(self, v: float) -> float:
        """dl/dv (mm/mL): zero past the table's end, where the length is held."""
        if v > self.v_end:
            return 0.0
        i = bisect.bisect_right(self._inner_knots, v)
        a, b, c, _ = self.l_coef[i]
        h = v - self.x[i]
        return (3 * a * h + 2 * b) * h + c


def growth_rate(slopes: Sequence[float], conductances: Sequence[float]) -> float:
    """How fast the segments' exchange runs away on its own (1/s; zero when stable):
    the largest positive eigenvalue r of the plant's Jacobian at segment slopes
    ``slopes`` (dp/dv, kPa/mL) and ``conductances`` c (mL/(kPa s)).

    A perturbation x of the volumes at a fixed pump volume (sum x = 0) grows as
    e^(rt) where r x_i = c_i (p_m' - k_i x_i), p_m' the manifold's change, so
    x_i = c_i p_m' / (r + c_i k_i) and sum x = 0 gives h(r) = sum c_i / (r + c_i k_i)
    = 0. h falls between its poles -c_i k_i, so the largest root lies between the two
    largest poles: none above zero unless a segment softens (k < 0), and with one
    softening segment one only if h(0) = sum 1/k_i > 0 (for two segments k1 + k2 < 0,
    the paper's Eq. 10). A single softening segment among stiff ones is therefore often
    stable: the others take up its volume.
    """
    pairs = [(c, k * c) for k, c in zip(slopes, conductances, strict=True)]
    poles = sorted(-ck for _, ck in pairs)
    if len(poles) < 2 or poles[-1] <= 0.0:
        return 0.0  # one segment takes the pump's volume: nothing to exchange
    low, top = poles[-2], poles[-1]
    if low == top:
        return top  # identical segments: their antisymmetric exchange, at the pole
    if low < 0.0:
        if sum(1.0 / k for k in slopes) <= 0.0:
            return 0.0  # h(0) <= 0: the root lies at or below zero
        low = 0.0
    # bisection: h > 0 just above ``low``, h < 0 just below ``top``; the bracket's
    # upper end, a rate a little above the root, limits the step
    for _ in range(12):
        middle = 0.5 * (low + top)
        if sum(c / (middle + ck) for c, ck in pairs) > 0.0:
            low = middle
        else:
            top = middle
    return top


class Plant:
    """The specimen's state as a function of the pump's volume history."""

    def __init__(
        self,
        segments: Sequence[SegmentCurve],
        volume_ml_at: Callable[[float], float],
        *,
        t0_s: float = 0.0,
        resistance_kpa_s_per_ml: float = 0.1,
        fittings_length_mm: float = 0.0,
        max_step_s: float = 0.2,
        max_step_volume_ml: float = 0.1,
        step_error_ml: float = 1e-4,
        step_bend_kpa: float = 0.01,
        history_s: float = 600.0,
        seed: int = 0,
        resistance_spread: float = 1e-3,
        behaviour: SpecimenBehaviour | None = None,
    ) -> None:
        if not segments:
            raise ValueError("a plant needs at least one segment")
        if resistance_kpa_s_per_ml <= 0:
            raise ValueError("the flow resistance must be > 0")
        self.segments = tuple(segments)
        self.volume_ml_at = volume_ml_at
        self.resistance = float(resistance_kpa_s_per_ml)
        self.fittings_length_mm = float(fittings_length_mm)
        self.max_step_s = float(max_step_s)
        self.max_step_volume_ml = float(max_step_volume_ml)
        self.step_error_ml = float(step_error_ml)
        self.step_bend_kpa = float(step_bend_kpa)
        self.history_s = float(history_s)
        self.behaviour = behaviour
        self._lock = threading.RLock()
        self._curves = [ScalarCurve(curve) for curve in self.segments]
        n = len(self.segments)
        # Tiny seeded differences between the connections break the symmetry of
        # identical segments the way a real rig does, deterministically for a seed.
        spread = np.random.default_rng(seed).normal(0.0, resistance_spread, n)
        self._conductances = (1.0 / (self.resistance * (1.0 + spread))).tolist()
        self._total_conductance = sum(self._conductances)
        self._t = float(t0_s)
        self._supplied_ml = float(volume_ml_at(t0_s))
        self._w = [self._supplied_ml / n] * n
        # (p, dp/dv) of each segment at ``_w``: the step that found ``_w`` evaluated
        # them there last, and the next step starts from them
        self._evaluated = self._evaluate(self._w)
        self._fastest_ml_s = 0.0  # the last step's fastest segment flow
        self._next_dt = 1e-3  # the step the last one's error allows (s)
        self._flows_ml_s = [0.0] * n  # the last step's flow into each segment
        self._history_t: list[float] = []
        self._history_p: list[float] = []
        self._history_l: list[float] = []
        self._history_w: list[list[float]] = []
        # the last step's sensor pressure (before the specimen's behaviour), its slope
        # over that step and the step's length: the next step's bend is measured on them
        self._inlet_last_kpa = self._inlet_kpa(0.0, [p for p, _ in self._evaluated])
        self._inlet_slope_kpa_s = 0.0
        self._last_dt = self._next_dt
        self._record(self._inlet_last_kpa)

    # --- state ---------------------------------------------------------------------
    @property
    def n(self) -> int:
        return len(self.segments)

    @property
    def t_s(self) -> float:
        return self._t

    @property
    def volumes_ml(self) -> np.ndarray:
        """Current volume supplied to each segment."""
        with self._lock:
            return np.array(self._w)

    def _length(self, w: list[float]) -> float:
        return sum(map(ScalarCurve.length, self._curves, w)) + self.fittings_length_mm

    def _evaluate(self, w: list[float]) -> list[tuple[float, float]]:
        """(p, dp/dv) of each segment at volumes ``w``."""
        return list(map(ScalarCurve.pressure_and_slope, self._curves, w))

    def _inlet_kpa(self, flow_ml_s: float, pressures: Sequence[float]) -> float:
        """The manifold (sensor) pressure (Q + sum c_i p_i) / C for segment
        ``pressures`` with the pump supplying ``flow_ml_s``."""
        weighted = sum(map(mul, self._conductances, pressures))
        return (flow_ml_s + weighted) / self._total_conductance

    def _record(self, inlet: float) -> None:
        """Append the state at ``_t`` (volumes ``_w``, sensor pressure ``inlet`` as the
        curves give it, changed by the specimen's behaviour if it has one)."""
        if self.behaviour is not None:
            inlet = self.behaviour.pressure_kpa(self._t, self._supplied_ml, inlet)
        self._history_t.append(self._t)
        self._history_p.append(inlet)
        self._history_l.append(self._length(self._w))
        self._history_w.append(self._w)  # a step makes a new list: never changed after
        if self._t - self._history_t[0] > 1.5 * self.history_s:
            cut = bisect.bisect_left(self._history_t, self._t - self.history_s)
            del self._history_t[:cut], self._history_p[:cut]
            del self._history_l[:cut], self._history_w[:cut]

    # --- dynamics ------------------------------------------------------------------
    def advance_to(self, t_s: float) -> None:
        """Integrate the plant up to time ``t_s`` (no-op for a time already passed)."""
        with self._lock:
            while self._t < t_s - 1e-12:
                self._step(min(self.max_step_s, t_s - self._t))

    def _step(self, dt: float) -> None:
        # the step the last one's error estimate allows, and no more than the last
        # one's fastest segment flow may cover (9/10 of it, for a flow that quickens)
        dt = min(dt, self._next_dt)
        if self._fastest_ml_s > 0:
            dt = min(dt, max(0.9 * self.max_step_volume_ml / self._fastest_ml_s, 1e-4))
        # an unstable exchange grows at ``growth_rate``; a backward Euler step longer
        # than ~1/rate would damp it into a false equilibrium. The rate is the last
        # step's, so the step is halved to it here, before any solve
        unstable_rate = growth_rate([k for _, k in self._evaluated], self._conductances)
        while dt * unstable_rate > 0.5:
            dt /= 2
        while True:
            supplied_next = float(self.volume_ml_at(self._t + dt))
            d_supplied = supplied_next - self._supplied_ml
            solved = self._solve_step(dt, d_supplied)
            if solved is not None:
                w_next, evaluated, inlet = solved
                moved = max(map(abs, map(sub, w_next, self._w)))
                # the errors over their tolerances: the step's own, and the sensor
                # pressure's bend between the step's ends, which the history draws as
                # a straight line (both grow as the step squared)
                over = max(
                    self._step_error_ml(dt, w_next) / self.step_error_ml,
                    self._bend_kpa(dt, inlet) / self.step_bend_kpa,
                )
                if dt < 1e-4 or (moved <= self.max_step_volume_ml and over <= 1.0):
                    break
                if moved <= self.max_step_volume_ml:
                    dt *= max(0.2, 0.9 / math.sqrt(over))
                    continue
            dt /= 2
        self._next_dt = dt * (min(0.9 / math.sqrt(over), 2.0) if over > 0 else 2.0)
        self._inlet_slope_kpa_s = (inlet - self._inlet_last_kpa) / dt
        self._inlet_last_kpa, self._last_dt = inlet, dt
        self._t += dt
        self._supplied_ml = supplied_next
        self._flows_ml_s = [(new - old) / dt for new, old in zip(w_next, self._w, strict=True)]
        self._w, self._evaluated = w_next, evaluated
        self._fastest_ml_s = moved / dt
        self._record(inlet)

    def _bend_kpa(self, dt: float, inlet: float) -> float:
        """How far the sensor pressure bends away from the straight line between a
        step's ends (kPa): dt^2/8 times its second derivative, estimated from the change
        of its slope since the last step. Where a segment's curve turns (its peak, the
        table's knots) the volume may move smoothly while the pressure does not."""
        slope = (inlet - self._inlet_last_kpa) / dt
        curvature = abs(slope - self._inlet_slope_kpa_s) / (0.5 * (dt + self._last_dt))
        return dt * dt / 8 * curvature

    def _step_error_ml(self, dt: float, w_next: list[float]) -> float:
        """The step's local error (mL, the largest of the segments'): a backward Euler
        step's is about dt^2/2 times the volume's second derivative, estimated from
        the flows' change over the step, dt/2 |q_new - q_old|."""
        return 0.5 * max(
            abs(new - old - dt * flow)
            for new, old, flow in zip(w_next, self._w, self._flows_ml_s, strict=True)
        )

    def _solve_step(
        self, dt: float, d_supplied: float
    ) -> tuple[list[float], list[tuple[float, float]], float] | None:
        """One backward Euler step: the new volumes, (p, dp/dv) of each segment there
        and the manifold pressure; or None when the step must be shorter.

        With conductances c_i = 1/R_i, C = sum c_i, the manifold pressure is
        p_m = (Q + sum c_j p_j) / C and segment i fills at c_i (p_m - p_i). Newton on
        r_i = w_i - w_i,old - dt c_i (p_m - p_i), whose Jacobian
        diag(1 + dt c_i k_i) - (dt c_i / C) (c k)^T is solved by Sherman-Morrison.
        """
        c, old = self._conductances, self._w
        total_c = self._total_conductance
        flow = d_supplied / dt
        # Newton starts from the last step's flows carried on (a smooth flow changes
        # little from one step to the next), their total made the pump's: fewer
        # evaluations a step than starting from the pump's volume split by conductance
        flows = self._flows_ml_s
        excess = (d_supplied - dt * sum(flows)) / total_c
        w = [wi + dt * fi + excess * ci for wi, fi, ci in zip(old, flows, c, strict=True)]
        # (dt c_i, dt c_i / C, c_i, old w_i) of each segment
        terms = [(dt * ci, dt * ci / total_c, ci, oi) for ci, oi in zip(c, old, strict=True)]
        # the plant takes tens of thousands of steps a run: each Newton iteration is one
        # pass over the segments for the manifold pressure and one for everything else,
        # with the same operations in the same order as the textbook form
        # (max |r|, min |diagonal|, the sums from the first segment on)
        for _ in range(30):
            evaluated = self._evaluate(w)
            p_m = self._inlet_kpa(flow, [p for p, _ in evaluated])
            largest_r = smallest_d = None
            sum_u = sum_r = 0.0
            steps = []
            for wi, (a, u, ci, oi), (pi, ki) in zip(w, terms, evaluated, strict=True):
                r = wi - oi - a * (p_m - pi)
                d = 1.0 + a * ki
                if largest_r is None or abs(r) > largest_r:
                    largest_r = abs(r)
                if smallest_d is None or abs(d) < smallest_d:
                    smallest_d = abs(d)
                if smallest_d < 1e-12:
                    continue  # singular: no step from here (unless converged)
                d_inv_r, d_inv_u, ck = r / d, u / d, ci * ki
                sum_u += ck * d_inv_u
                sum_r += ck * d_inv_r
                steps.append((d_inv_r, d_inv_u))
            if largest_r < 1e-11:
                return w, evaluated, p_m
            if smallest_d < 1e-12:
                return None
            denominator = 1.0 - sum_u
            if abs(denominator) < 1e-12:
                return None
            factor = sum_r / denominator
            w = [wi - (x + y * factor) for wi, (x, y) in zip(w, steps, strict=True)]
        return None

    # --- queries -------------------------------------------------------------------
    def pressure_kpa_at(self, t_s) -> np.ndarray:
        """Inlet (sensor) pressure at the given times, advancing as needed."""
        return self._interpolate(t_s, self._history_p)

    def length_mm_at(self, t_s) -> np.ndarray:
        """Specimen length (segments plus fittings) at the given times (an array, or
        one float for one float)."""
        return self._interpolate(t_s, self._history_l)

    def _interpolate(self, t_s, series: list[float]) -> np.ndarray:
        if isinstance(t_s, float):
            return self._interpolate_one(t_s, series)
        t = np.asarray(t_s, dtype=float)
        with self._lock:
            if t.size == 0:
                return np.empty_like(t)
            t_lo, t_hi = float(t.min()), float(t.max())
            self.advance_to(t_hi)
            history_t = self._history_t
            if t_lo < history_t[0] - 1e-9:
                raise ValueError(
                    f"plant history starts at {history_t[0]:.3f} s; asked for {t_lo:.3f} s"
                )
            # only the stretch of history the query spans: the history holds tens of
            # thousands of steps and the DAQ, the camera and the pump ask many times a
            # second
            first = max(bisect.bisect_right(history_t, t_lo) - 1, 0)
            last = min(bisect.bisect_left(history_t, t_hi) + 1, len(history_t))
            return np.interp(t, history_t[first:last], series[first:last])

    def _interpolate_one(self, t_s: float, series: list[float]) -> float:
        """One time (the camera asks 30 times a second): linear between the two steps
        around it, without numpy's per-call cost."""
        with self._lock:
            self.advance_to(t_s)
            history_t = self._history_t
            if t_s < history_t[0] - 1e-9:
                raise ValueError(
                    f"plant history starts at {history_t[0]:.3f} s; asked for {t_s:.3f} s"
                )
            j = bisect.bisect_right(history_t, t_s)
            if j == 0:
                return series[0]
            if j == len(history_t):
                return series[-1]
            t0, t1 = history_t[j - 1], history_t[j]
            return series[j - 1] + (series[j] - series[j - 1]) * (t_s - t0) / (t1 - t0)
