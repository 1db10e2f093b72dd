"""The paper's own algorithm, kept as a slow, independent reference for the fast path.

Small volume increments; at each, a local Nelder-Mead minimisation of the reduced energy
E~(v_1..v_{n-1}) (Eq. 4, v_n from Eq. 2) starting from the previous state, as the paper
did in Matlab. It shares only the segment curves with ``labrig.model.actuator.path``: no
branches, no folds, no flow. Two of the model-notes' traps are avoided as the notes say:

- the initial simplex is a tenth of the volume increment (trap 2): the default 5 %
  simplex hops over a shrinking barrier and predicts snaps early, and even a simplex
  the size of the increment hops, at coincident peaks (B46-T20 + B46-T22), from the
  stable branch the state is on to a disconnected one (trap 1);
- the energy minimised is the difference from the previous state, integrated piece by
  piece from small terms (trap 3): absolute energies (~10^3 mJ) would hide the
  differences below 1e-9 mJ that decide a minimum near a peak.

A snap is detected, as in the paper, as a jump of the state between two increments
larger than ``jump_ml``; a transition as a change of the number of segments right of
their peak (alpha) or a snap. Transition volumes are therefore known to one increment.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from labrig.model.actuator.curve_tables import reduced_energy_change, tables_of
from labrig.model.actuator.equilibria import Actuator


@dataclass(frozen=True)
class ReferenceTransition:
    """A transition as the incremental algorithm sees it, between two increments."""

    v_ml: float  # the last volume before it
    alpha: int
    beta: int
    stable: bool
    direction: int
    v_i_pre_ml: tuple[float, ...]
    v_i_post_ml: tuple[float, ...]  # at v_ml + one increment


@dataclass(frozen=True)
class ReferencePath:
    v_ml: np.ndarray  # (N,)
    v_i_ml: np.ndarray  # (N, n)
    p_kpa: np.ndarray  # (N,) mean of the segment pressures
    transitions: tuple[ReferenceTransition, ...]


def reference_path(
    actuator: Actuator,
    v_end_ml: float,
    *,
    dv_ml: float = 0.01,
    deflate: bool = False,
    jump_ml: float | None = None,
    simplex_fraction: float = 0.1,
) -> ReferencePath:
    """Inflate in steps of ``dv_ml`` to ``v_end_ml`` (then back to 0 if ``deflate``),
    minimising locally at each step.

    ``jump_ml`` (default 3 sqrt(dv_ml)) is the state change between two increments that
    counts as a snap. Approaching a fold the state moves like the square root of the
    volume left (about 1.5 sqrt(dv_ml) in the last increment), so a fixed threshold
    would either flag the approach or miss small snaps at fine increments.
    """
    from scipy.optimize import minimize  # heavy: only the reference needs it

    kernels = actuator.kernels
    tables = tables_of(tuple(kernels))
    n = actuator.n
    jump_ml = 3.0 * math.sqrt(dv_ml) if jump_ml is None else jump_ml
    steps = math.ceil(v_end_ml / dv_ml - 1e-9)
    volumes = [min(j * dv_ml, v_end_ml) for j in range(steps + 1)]
    if deflate:
        volumes += volumes[-2::-1]
    w = [0.0] * n
    states = [tuple(w)]
    transitions = []
    branches = [kern.branch_of(x) for kern, x in zip(kernels, w, strict=True)]
    for j in range(1, len(volumes)):
        v = volumes[j]
        direction = 1 if v > volumes[j - 1] else -1
        previous = list(w)
        x0 = np.array(previous[:-1])
        simplex = np.vstack([x0, x0 + simplex_fraction * dv_ml * np.eye(n - 1)])
        result = minimize(
            reduced_energy_change,
            x0,
            args=(tables, np.array(previous), v),
            method="Nelder-Mead",
            options={"initial_simplex": simplex, "xatol": 1e-8, "fatol": 1e-12, "maxiter": 20_000},
        )
        x = [float(a) for a in result.x]
        w = [*x, v - math.fsum(x)]
        new_branches = [kern.branch_of(a) for kern, a in zip(kernels, w, strict=True)]
        jump = max(abs(a - b) for a, b in zip(w, previous, strict=True)) > jump_ml
        alpha = actuator.alpha(branches)
        beta = actuator.alpha(new_branches)
        if jump or alpha != beta:
            transitions.append(
                ReferenceTransition(
                    volumes[j - 1], alpha, beta, not jump, direction, tuple(previous), tuple(w)
                )
            )
        branches = new_branches
        states.append(tuple(w))
    v_i = np.array(states)
    p = np.array([[kern.pressure(a) for kern, a in zip(kernels, s, strict=True)] for s in states])
    return ReferencePath(np.array(volumes), v_i, p.mean(axis=1), tuple(transitions))
