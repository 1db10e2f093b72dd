"""Where a lost state goes: the overdamped flow between segments at constant volume.

When the path loses its state (a fold, or coincident branch ends with no stable way on),
fluid redistributes at constant total volume. With equal flow resistances between the
segments and negligible inertia (the water takes about a second, Movie S7), segment i
gains volume at a rate proportional to the pressure difference to the others:

    dw_i/dt = -(p_i(w_i) - mean_j p_j(w_j)),    sum_i w_i = v fixed,

which is the steepest descent of the total energy on the plane sum w = v. Where it ends
is the state after the snap: not the lowest-energy equilibrium at
that volume, and for n >= 3 not necessarily the one a minimiser would find.

For two segments the flow is one-dimensional and monotone, so it ends at the first zero
of p_1(w_1) - p_2(v - w_1) in the direction it starts: found exactly by a scan over the
samples of both curves and a bracketed root. For n >= 3 the flow is integrated with an
L-stable Rosenbrock method (ROS2, Verwer et al. 1999): the stiffening walls make the
system stiff, and its Jacobian is diagonal plus rank one, so each linear solve is a
Sherman-Morrison formula on floats. Near the end the steps grow and the method becomes
Newton's, so the end state is an equilibrium to rounding. The integrator is compiled
(``labrig.model.actuator.rosenbrock_flow``): it is most of a scan's work.

This module returns volumes only; ``labrig.model.actuator.path`` turns them into a state on a
branch combination and checks it is stable.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from labrig.model.actuator import rosenbrock_flow
from labrig.model.actuator.curve_tables import PAIR_IMBALANCE, pair_imbalance, tables_of
from labrig.model.actuator.equilibria import hessian, stable_scalar
from labrig.model.actuator.kernel import CurveKernel
from labrig.model.actuator.roots import XTOL, bracketed_root

# pushes off unstable equilibria before a flow is declared stuck
MAX_SADDLE_ESCAPES = 100
# default local error per flow step, in units of the tables' sample spacing (``settle``)
FLOW_TOL = 0.5
_NO_BRANCHES = np.zeros(0, dtype=np.int64)  # the pair's root needs none


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
    if len(kernels) == 2:
        w = list(w0)
        for _ in range(10):
            w = _settle_pair(kernels, w)
            k = [kern.slope(x) for kern, x in zip(kernels, w, strict=True)]
            if stable_scalar(k):
                return w
            w = _escape_saddle(w, k, 1e-2 * unit)
        raise FlowError(
            f"the flow keeps stalling on unstable equilibria near {[float(x) for x in w]}"
        )
    tables = tables_of(tuple(kernels))
    w = np.array(w0, dtype=float)
    for _ in range(MAX_SADDLE_ESCAPES):
        status, w = rosenbrock_flow.settle_flow(tables, w, tol * unit, unit, max_steps)
        if status == rosenbrock_flow.SETTLED:
            return w.tolist()
        if status == rosenbrock_flow.MAX_STEPS:
            raise FlowError(f"the flow did not settle in {max_steps} steps (volumes {w.tolist()})")
        # at rest on an unstable equilibrium (a saddle, or extrema that coincide)
        k = [kern.slope(x) for kern, x in zip(kernels, w.tolist(), strict=True)]
        w = np.array(_escape_saddle(w.tolist(), k, 1e-2 * unit))
    raise FlowError(f"the flow keeps stalling on unstable equilibria near {w.tolist()}")


def volume_unit_ml(kernels: Sequence[CurveKernel]) -> float:
    """The volume scale of the actuator, to which the solver's volume tolerances are
    tied: the mean sample spacing of the segments' tables, rounded to a power of ten.
    The rounding keeps the tolerances the solver was validated with on the library
    (spacing ~0.1 mL: flow steps of 0.05 mL, snap starts 0.01 mL from the fold) exactly
    as they were, and an actuator scaled by a power of ten is solved alike."""
    spacing = sum((k.v_last - k.v_first) / (len(k.x) - 1) for k in kernels) / len(kernels)
    return 10.0 ** round(math.log10(spacing))


# --- two segments: exact ---------------------------------------------------------------
def _settle_pair(kernels: Sequence[CurveKernel], w: list[float]) -> list[float]:
    first, second = kernels
    v = w[0] + w[1]
    args = (tables_of(tuple(kernels)), v)

    def imbalance(w1: float) -> float:  # p_1 - p_2; the flow moves w1 against its sign
        return pair_imbalance(w1, *args)

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
    w1 = bracketed_root(PAIR_IMBALANCE, args[0], _NO_BRANCHES, v, a, b, math.nan, math.nan, XTOL)
    return [w1, v - w1]


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
