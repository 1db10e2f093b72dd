"""Where a lost state goes: the overdamped flow between segments at constant volume.

When the path loses its state (a fold, or coincident branch ends with no stable way on),
fluid redistributes at constant total volume. With equal flow resistances between the
segments and negligible inertia (the water takes about a second, Movie S7), segment i
gains volume at a rate proportional to the pressure difference to the others:

    dw_i/dt = -(p_i(w_i) - mean_j p_j(w_j)),    sum_i w_i = v fixed,

which is the steepest descent of the total energy on the plane sum w = v. Where it ends
is the state after the snap (model-notes, trap 9): not the lowest-energy equilibrium at
that volume, and for n >= 3 not necessarily the one a minimiser would find.

For two segments the flow is one-dimensional and monotone, so it ends at the first zero
of p_1(w_1) - p_2(v - w_1) in the direction it starts: found exactly by a scan over the
samples of both curves and a bracketed root. For n >= 3 the flow is integrated with an
L-stable Rosenbrock method (ROS2, Verwer et al. 1999): the stiffening walls make the
system stiff, and its Jacobian is diagonal plus rank one, so each linear solve is a
Sherman-Morrison formula on floats. Near the end the steps grow and the method becomes
Newton's, so the end state is an equilibrium to rounding.

This module returns volumes only; ``labrig.model.path`` turns them into a state on a
branch combination and checks it is stable.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from labrig.model.actuator import hessian, stable_scalar
from labrig.model.kernel import CurveKernel
from labrig.model.roots import bracketed_root

_GAMMA = 1.0 + 1.0 / math.sqrt(2.0)  # ROS2, L-stable
# default local error per flow step, in units of the tables' sample spacing (``settle``)
FLOW_TOL = 0.5


class FlowError(RuntimeError):
    """The flow did not settle (a bug or a curve outside the model's assumptions)."""


def settle(
    kernels: Sequence[CurveKernel],
    w0: Sequence[float],
    *,
    tol: float = FLOW_TOL,
    max_steps: int = 200_000,
) -> list[float]:
    """Follow the flow from ``w0`` (volumes, mL) to the stable state where it ends.

    ``tol`` bounds the local error of each flow step, as a fraction of the volume unit
    of the segments' tables (``volume_unit_ml``, 0.1 mL for the library), so that
    actuators of microlitres and of litres are integrated alike. Only the basin
    the flow ends in matters (the end state is an exact equilibrium either way): on 300
    random library triples and quadruples, tolerances from 1e-5 to 0.1 mL give the same
    transitions, the same post-snap states and volumes equal to 1e-8 mL.

    A start on an unstable equilibrium (a symmetric state of identical segments) is
    pushed off it in a fixed direction, so the result is deterministic.
    """
    unit = volume_unit_ml(kernels)
    w = list(w0)
    for _ in range(10):
        if len(kernels) == 2:
            w = _settle_pair(kernels, w)
        else:
            w = _settle_flow(kernels, w, tol_ml=tol * unit, unit_ml=unit, max_steps=max_steps)
        k = [kern.slope(x) for kern, x in zip(kernels, w, strict=True)]
        if stable_scalar(k):
            return w
        w = _escape_saddle(w, k, 1e-2 * unit)
    raise FlowError(f"the flow keeps stalling on unstable equilibria near {w}")


def volume_unit_ml(kernels: Sequence[CurveKernel]) -> float:
    """The volume scale of the actuator, to which the solver's volume tolerances are
    tied: the mean sample spacing of the segments' tables, rounded to a power of ten.
    The rounding keeps the tolerances the solver was validated with on the library
    (spacing ~0.1 mL: flow steps of 0.05 mL, snap starts 0.01 mL from the fold) exactly
    as they were, and an actuator scaled by a power of ten is solved alike."""
    spacing = sum((k.v_last - k.v_first) / (len(k.x) - 1) for k in kernels) / len(kernels)
    return 10.0 ** round(math.log10(spacing))


def flow_rate(kernels: Sequence[CurveKernel], w: Sequence[float]) -> list[float]:
    """dw_i/dt = -(p_i - mean p) at volumes ``w``."""
    p = [kern.pressure(x) for kern, x in zip(kernels, w, strict=True)]
    mean = sum(p) / len(p)
    return [mean - x for x in p]


# --- two segments: exact ---------------------------------------------------------------
def _settle_pair(kernels: Sequence[CurveKernel], w: list[float]) -> list[float]:
    first, second = kernels
    v = w[0] + w[1]

    def imbalance(w1: float) -> float:  # p_1 - p_2; the flow moves w1 against its sign
        return first.pressure(w1) - second.pressure(v - w1)

    g0 = imbalance(w[0])
    if g0 == 0.0:
        return w
    direction = -1.0 if g0 > 0 else 1.0
    # Candidate points: every sample of either curve between here and the end of the
    # range; between two of them both pressures are single monotone cubics.
    end = 0.0 if direction < 0 else v
    knots = np.concatenate([np.asarray(first.x), v - np.asarray(second.x)])
    lo, hi = min(w[0], end), max(w[0], end)
    points = np.unique(np.concatenate([knots[(knots > lo) & (knots < hi)], [end]]))
    if direction < 0:
        points = points[::-1]
    values = np.array([imbalance(x) for x in points])
    crossed = np.flatnonzero(direction * values >= 0)
    if len(crossed) == 0:
        # past the end of the range the linear continuations take over; extend once
        far = end + direction * max(v, 1.0)
        if direction * imbalance(far) < 0:
            raise FlowError("the flow between two segments never stops")
        a, b = end, far
    else:
        j = crossed[0]
        a = w[0] if j == 0 else float(points[j - 1])
        b = float(points[j])
    w1 = bracketed_root(imbalance, a, b)
    return [w1, v - w1]


# --- n >= 3: ROS2 on the flow ----------------------------------------------------------
def _step_limit(h: float, k: list[float]) -> float:
    """``h``, or less so that gamma*h*|mu| <= 1/2 for the flow's fastest unstable rate mu.

    A linearly implicit step with gamma*h*|mu| > 1 turns an unstable direction into a
    contracting one (it would walk back onto the fold it left). The rates are the
    eigenvalues mu of the Hessian on the plane sum w = 0, the roots of
    sum_i 1/(k_i - mu) = 0 (secular equation); the lowest lies between the two smallest
    k_i, where that sum increases with mu. One evaluation at mu* = -1/(2 gamma h) tells
    whether h is short enough; if not, mu is found by bisection to 1 %. Limiting by the
    rate rather than by the most negative k_i matters near a fold, where the rate is ~0
    and the flow needs long steps to leave it.
    """
    k_sorted = sorted(k)
    lo = k_sorted[0]
    if lo >= 0:
        return h
    hi = min(k_sorted[1], 0.0)
    mu = -0.5 / (_GAMMA * h)
    if mu <= lo or (mu < hi and sum(1.0 / (x - mu) for x in k) <= 0):
        return h  # the lowest rate is above mu*
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        if sum(1.0 / (x - mid) for x in k if x != mid) > 0:
            hi = mid
        else:
            lo = mid
        if hi - lo <= 0.01 * abs(lo):
            break
    return min(h, 0.5 / (_GAMMA * -lo)) if lo < 0 else h


def _solve(h: float, k: list[float], rhs: list[float]) -> list[float] | None:
    """Solve (I - gamma h J) x = rhs, J = -(diag(k) - (1/n) 1 k^T), by Sherman-Morrison;
    None if the matrix is (nearly) singular for this step size.

    With D = diag(1 + gamma h k_i) the Sherman-Morrison denominator
    1 - (gamma h / n) sum k_i/d_i equals mean(1/d_i) exactly, which is how it is
    computed: the textbook form cancels to nothing for long steps.
    """
    n = len(k)
    gh = _GAMMA * h
    d = [1.0 + gh * x for x in k]
    if min(abs(x) for x in d) < 1e-12:
        return None
    inverse = [1.0 / x for x in d]
    denominator = math.fsum(inverse) / n
    if abs(denominator) < 1e-12 * max(abs(x) for x in inverse):
        return None
    y = [r * q for r, q in zip(rhs, inverse, strict=True)]
    scale = (gh / n) * math.fsum(x * yi for x, yi in zip(k, y, strict=True)) / denominator
    return [yi + scale * q for yi, q in zip(y, inverse, strict=True)]


def _newton_step_size(k: list[float], f: list[float]) -> float:
    """Length (max norm, mL) of the Newton step to the nearest equilibrium on the plane
    sum w = v: x_i = (f_i + lam)/k_i with lam set by sum x_i = 0. Small only near a
    non-degenerate equilibrium; near a fold (sum 1/k ~ 0) it is large, so a state that
    merely sits on the slow ghost of a fold is not mistaken for the end of the flow."""
    if any(x == 0.0 for x in k):
        return math.inf
    inverse_sum = math.fsum(1.0 / x for x in k)
    if inverse_sum == 0.0:
        return math.inf
    lam = -math.fsum(a / x for a, x in zip(f, k, strict=True)) / inverse_sum
    return max(abs((a + lam) / x) for a, x in zip(f, k, strict=True))


def _escape_saddle(w: list[float], k: list[float], push_ml: float) -> list[float]:
    """Push a state stalled on a saddle along its most unstable direction, with a fixed
    sign (the first non-zero component positive), so that symmetric cases are
    deterministic."""
    values, vectors = np.linalg.eigh(hessian(k))
    e = vectors[:, int(np.argmin(values))]
    u = np.append(e, -e.sum())
    u = u / np.max(np.abs(u))
    if u[np.flatnonzero(np.abs(u) > 1e-12)[0]] < 0:
        u = -u
    return [x + push_ml * ui for x, ui in zip(w, u, strict=True)]


def _settle_flow(
    kernels: Sequence[CurveKernel],
    w: list[float],
    *,
    tol_ml: float,
    unit_ml: float,
    max_steps: int,
) -> list[float]:
    n = len(w)
    h = 1e-3
    rejected = False
    p, k = _pressures_and_slopes(kernels, w)
    for _ in range(max_steps):
        mean = sum(p) / n
        f = [mean - x for x in p]
        at_rest = max(abs(x) for x in f) <= 1e-12 * max(1.0, abs(mean))
        if at_rest or _newton_step_size(k, f) < 1e-9 * unit_ml:
            if stable_scalar(k):
                return w
            if at_rest:  # an unstable equilibrium (a saddle, or extrema that coincide)
                w = _escape_saddle(w, k, 1e-2 * unit_ml)
                p, k = _pressures_and_slopes(kernels, w)
                h = 1e-3
                continue
        h = _step_limit(h, k)
        k1 = _solve(h, k, f)
        if k1 is None:
            h *= 0.25
            continue
        f_mid = flow_rate(kernels, [x + h * y for x, y in zip(w, k1, strict=True)])
        k2 = _solve(h, k, [a - 2.0 * b for a, b in zip(f_mid, k1, strict=True)])
        if k2 is None:
            h *= 0.25
            continue
        # the embedded first-order difference, filtered through (I - gamma h J)^-1 so
        # that relaxed stiff components (a segment on its stiffening wall) do not count
        # (Shampine's filter for stiff error estimates)
        filtered = _solve(h, k, [0.5 * h * (a + b) for a, b in zip(k1, k2, strict=True)])
        error = max(abs(x) for x in filtered) if filtered is not None else 4.0 * tol_ml
        step = [h * (1.5 * a + 0.5 * b) for a, b in zip(k1, k2, strict=True)]
        # the exact step keeps sum w; rounding in sum f, times a long step, would not
        drift = sum(step) / n
        step = [d - drift for d in step]
        w_new = [x + d for x, d in zip(w, step, strict=True)]
        p_new, k_new = _pressures_and_slopes(kernels, w_new)
        # A gradient flow only loses energy (dE/dt = -sum (p_i - mean p)^2): a step that
        # gains some is wrong however small its error estimate (this stops the method
        # from cycling where the Jacobian changes fast, next to coincident extrema).
        # The change is integral p dw by the Hermite rule from both ends' p and p'.
        gained = sum(
            d * (0.5 * (pa + pb) + d * (ka - kb) / 12.0)
            for d, pa, pb, ka, kb in zip(step, p, p_new, k, k_new, strict=True)
        )
        lost_energy = gained <= 1e-12 * sum(abs(d * x) for d, x in zip(step, p, strict=True))
        accepted = error <= tol_ml and lost_energy
        if accepted:
            w, p, k = w_new, p_new, k_new
        elif not lost_energy:
            error = max(error, 4.0 * tol_ml)
        factor = 0.8 * math.sqrt(tol_ml / error) if error > 0 else 5.0
        # no growth right after a rejection (avoids alternating reject/accept)
        h *= min(5.0 if accepted and not rejected else 1.0, max(0.2, factor))
        rejected = not accepted
    raise FlowError(f"the flow did not settle in {max_steps} steps (volumes {w})")


def _pressures_and_slopes(
    kernels: Sequence[CurveKernel], w: Sequence[float]
) -> tuple[list[float], list[float]]:
    pk = [kern.pressure_and_slope(x) for kern, x in zip(kernels, w, strict=True)]
    return [a for a, _ in pk], [b for _, b in pk]
