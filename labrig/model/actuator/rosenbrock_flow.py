"""The n >= 3 flow integrator of ``labrig.model.actuator.descent``, compiled with numba.

The flow after a snap is where a scan spends most of its time: about 4 flows per
quadruple, 50-150 Rosenbrock steps each, each step a handful of piecewise-cubic
evaluations and three Sherman-Morrison solves on n floats. In CPython that is ~5 ms per
flow (60 % of a quadruple); compiled, ~0.1 ms. The algorithm is the one described in
``labrig.model.actuator.descent`` (ROS2, Shampine's filtered error estimate, the energy check,
the step limit from the secular equation); the sums that the pure-Python version took
with ``math.fsum`` are compensated (Neumaier) sums here, so the rounding is the same.

It reads the actuator's curves as packed arrays (``labrig.model.actuator.curve_tables``).
Compilation takes a few seconds once; the machine code is cached next to this file
(``cache=True``) and reused by every later process, including scan workers.
"""

from __future__ import annotations

import math

import numpy as np

from labrig.model.actuator.curve_tables import compensated_sum, pressure_and_slope
from labrig.model.actuator.equilibria import stable_slopes
from labrig.model.actuator.jit import INTERNAL_LEAF, njit

GAMMA = 1.0 + 1.0 / math.sqrt(2.0)  # ROS2, L-stable

SETTLED = 0  # a stable equilibrium
SADDLE = 1  # at rest on an unstable equilibrium: the caller pushes it off
MAX_STEPS = 2  # the step budget ran out


@njit(**INTERNAL_LEAF)
def _state(tables, w, p, k):
    for i in range(len(w)):
        p[i], k[i] = pressure_and_slope(tables, i, w[i])


@njit(**INTERNAL_LEAF)
def _step_limit(h, k):
    """See ``descent``: h, or less so that gamma h |mu| <= 1/2 for the flow's fastest
    unstable rate mu (the secular equation sum 1/(k_i - mu) = 0)."""
    lo, second = math.inf, math.inf  # the two smallest k
    for a in k:
        if a < lo:
            lo, second = a, lo
        elif a < second:
            second = a
    if lo >= 0:
        return h
    hi = min(second, 0.0)
    mu = -0.5 / (GAMMA * h)
    if mu <= lo:
        return h
    if mu < hi:
        total = 0.0
        for a in k:
            total += 1.0 / (a - mu)
        if total <= 0:
            return h
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        total = 0.0
        for a in k:
            if a != mid:
                total += 1.0 / (a - mid)
        if total > 0:
            hi = mid
        else:
            lo = mid
        if hi - lo <= 0.01 * abs(lo):
            break
    return min(h, 0.5 / (GAMMA * -lo)) if lo < 0 else h


@njit(**INTERNAL_LEAF)
def _solve(h, k, rhs, out, inverse, work):
    """(I - gamma h J) out = rhs by Sherman-Morrison (see ``descent``); False if the
    matrix is (nearly) singular for this step size. ``inverse`` and ``work`` are
    scratch arrays of length n (no allocation in the flow's loop)."""
    n = len(k)
    gh = GAMMA * h
    biggest = 0.0
    for i in range(n):
        d = 1.0 + gh * k[i]
        if abs(d) < 1e-12:
            return False
        inverse[i] = 1.0 / d
        biggest = max(biggest, abs(inverse[i]))
    denominator = compensated_sum(inverse) / n
    if abs(denominator) < 1e-12 * biggest:
        return False
    for i in range(n):
        out[i] = rhs[i] * inverse[i]  # y
        work[i] = k[i] * out[i]
    scale = (gh / n) * compensated_sum(work) / denominator
    for i in range(n):
        out[i] = out[i] + scale * inverse[i]
    return True


@njit(**INTERNAL_LEAF)
def _newton_step_size(k, f, work):
    """Max-norm length of the Newton step to the nearest equilibrium (see ``descent``)."""
    n = len(k)
    for a in k:
        if a == 0.0:
            return math.inf
    for i in range(n):
        work[i] = 1.0 / k[i]
    inverse_sum = compensated_sum(work)
    if inverse_sum == 0.0:
        return math.inf
    for i in range(n):
        work[i] = f[i] / k[i]
    lam = -compensated_sum(work) / inverse_sum
    size = 0.0
    for i in range(n):
        size = max(size, abs((f[i] + lam) / k[i]))
    return size


@njit(**INTERNAL_LEAF)
def _mean(values):
    total = 0.0
    for a in values:
        total += a
    return total / len(values)


@njit(cache=True)
def settle_flow(tables, w0, tol_ml, unit_ml, max_steps):
    """Integrate the flow from ``w0`` until it rests. Returns (status, w): SETTLED on a
    stable equilibrium, SADDLE at rest on an unstable one, MAX_STEPS otherwise. Every
    array is allocated once, before the loop."""
    n = len(w0)
    w = w0.copy()
    h = 1e-3
    rejected = False
    p, k, p_new, k_new = np.empty(n), np.empty(n), np.empty(n), np.empty(n)
    f, k1, k2, filtered = np.empty(n), np.empty(n), np.empty(n), np.empty(n)
    rhs, trial, step = np.empty(n), np.empty(n), np.empty(n)
    inverse, work = np.empty(n), np.empty(n)
    _state(tables, w, p, k)
    for _ in range(max_steps):
        mean = _mean(p)
        largest = 0.0
        for i in range(n):
            f[i] = mean - p[i]
            largest = max(largest, abs(f[i]))
        at_rest = largest <= 1e-12 * max(1.0, abs(mean))
        if at_rest or _newton_step_size(k, f, work) < 1e-9 * unit_ml:
            if stable_slopes(k):
                return SETTLED, w
            if at_rest:
                return SADDLE, w
        h = _step_limit(h, k)
        if not _solve(h, k, f, k1, inverse, work):
            h *= 0.25
            continue
        for i in range(n):
            trial[i] = w[i] + h * k1[i]
        _state(tables, trial, p_new, k_new)
        mean_mid = _mean(p_new)
        for i in range(n):
            rhs[i] = (mean_mid - p_new[i]) - 2.0 * k1[i]
        if not _solve(h, k, rhs, k2, inverse, work):
            h *= 0.25
            continue
        # Shampine's filtered error estimate: relaxed stiff components do not count
        for i in range(n):
            rhs[i] = 0.5 * h * (k1[i] + k2[i])
        if _solve(h, k, rhs, filtered, inverse, work):
            error = 0.0
            for i in range(n):
                error = max(error, abs(filtered[i]))
        else:
            error = 4.0 * tol_ml
        for i in range(n):
            step[i] = h * (1.5 * k1[i] + 0.5 * k2[i])
        drift = _mean(step)  # the exact step keeps sum w; rounding would not
        stage = 0.0
        progress = 0.0
        for i in range(n):
            step[i] = step[i] - drift
            trial[i] = w[i] + step[i]
            stage = max(stage, abs(k1[i]))
            progress = max(progress, abs(step[i]))
        _state(tables, trial, p_new, k_new)
        # a gradient flow only loses energy: a step that gains some is wrong (Hermite
        # rule for the integral of p dw from both ends' p and p')
        gained = 0.0
        moved = 0.0
        for i in range(n):
            gained += step[i] * (0.5 * (p[i] + p_new[i]) + step[i] * (k[i] - k_new[i]) / 12.0)
            moved += abs(step[i] * p[i])
        lost_energy = gained <= 1e-12 * moved
        # a trial stage that jumps a wall (a rise narrower than the step) makes the
        # second stage cancel the first: the step moves nothing while its error estimate
        # passes, and would repeat at the same h for ever
        cancelled = progress <= 1e-9 * h * stage
        accepted = error <= tol_ml and lost_energy and not cancelled
        if accepted:
            w, trial = trial, w
            p, p_new = p_new, p
            k, k_new = k_new, k
        elif not lost_energy or cancelled:
            error = max(error, 4.0 * tol_ml)
        factor = 0.8 * math.sqrt(tol_ml / error) if error > 0 else 5.0
        # no growth right after a rejection (avoids alternating reject/accept)
        h *= min(5.0 if accepted and not rejected else 1.0, max(0.2, factor))
        rejected = not accepted
    return MAX_STEPS, w
