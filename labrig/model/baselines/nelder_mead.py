"""The paper's own algorithm, kept as a slow, independent reference for the fast path.

Small volume increments; at each, a local Nelder-Mead minimisation of the reduced energy
E~(v_1..v_{n-1}) (Eq. 4, v_n from Eq. 2) starting from the previous state, as the paper
did in Matlab. It shares only the segment curves with ``labrig.model.actuator.path``: no
branches, no folds, no flow. Two numerical traps of that algorithm are avoided:

- the initial simplex is a tenth of the volume increment: the default 5 %
  simplex hops over a shrinking barrier and predicts snaps early, and even a simplex
  the size of the increment hops, at coincident peaks (B46-T20 + B46-T22), from the
  stable branch the state is on to a disconnected one;
- the energy minimised is the difference from the previous state, integrated piece by
  piece from small terms: absolute energies (~10^3 mJ) would hide the
  differences below 1e-9 mJ that decide a minimum near a peak.

The minimiser is scipy's Nelder-Mead (``scipy.optimize.minimize(method="Nelder-Mead")``,
non-adaptive, no bounds) step for step, compiled with its objective
(``minimise_energy_change``): scipy's own loop runs in Python around the objective, and
that overhead, not the energy, would be nearly all of the reference's time. The same
operations in the same order give the same states as scipy's, bit for bit, wherever
scipy's own order of vertices is defined (``_order_vertices``;
tests/model/baselines/test_nelder_mead.py holds them to it).

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
from labrig.model.actuator.jit import INTERNAL_LEAF, njit

# scipy's tolerances for the reference: far below one increment, and fatol far below the
# energy differences (below 1e-9 mJ) that decide a minimum near a peak
XATOL_ML = 1e-8
FATOL_MJ = 1e-12
MAXITER = 20_000


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
        found, _ = minimise_energy_change(
            simplex, tables, np.array(previous), v, XATOL_ML, FATOL_MJ, MAXITER
        )
        x = [float(a) for a in found]
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


@njit(cache=True)
def minimise_energy_change(simplex, tables, previous, v, xatol, fatol, maxiter):
    """The minimum of ``reduced_energy_change(x, tables, previous, v)`` near
    ``simplex[0]``, by scipy's Nelder-Mead from the initial simplex ``simplex`` (N+1, N)
    with its options ``xatol``, ``fatol`` and ``maxiter`` (no ``maxfev``). Returns (x,
    the number of evaluations).

    scipy's coefficients (rho 1, chi 2, psi 1/2, sigma 1/2) are written out in its own
    products, so that no rounding differs. Rows are copied element by element: numba
    compiles a slice assignment into general broadcasting code, which tripled the
    compile time (1.4 s against 3.8 s of CPU, a fresh install's one-off cost).
    """
    sim = simplex.copy()
    npts, dim = sim.shape
    fsim = np.empty(npts)
    for j in range(npts):
        fsim[j] = reduced_energy_change(sim[j], tables, previous, v)
    evaluations = npts
    _order_vertices(sim, fsim)
    centroid = np.empty(dim)
    reflected = np.empty(dim)
    trial = np.empty(dim)
    iterations = 1
    while iterations < maxiter:
        if _spread(sim, fsim, True) <= xatol and _spread(sim, fsim, False) <= fatol:
            break
        for k in range(dim):  # numpy's add.reduce over rows: row by row
            total = sim[0, k]
            for j in range(1, dim):
                total += sim[j, k]
            centroid[k] = total / dim
        for k in range(dim):
            reflected[k] = 2.0 * centroid[k] - 1.0 * sim[dim, k]
        f_reflected = reduced_energy_change(reflected, tables, previous, v)
        evaluations += 1
        if f_reflected < fsim[0]:  # expand
            for k in range(dim):
                trial[k] = 3.0 * centroid[k] - 2.0 * sim[dim, k]
            f_trial = reduced_energy_change(trial, tables, previous, v)
            evaluations += 1
            if f_trial < f_reflected:
                _set_vertex(sim, fsim, dim, trial, f_trial)
            else:
                _set_vertex(sim, fsim, dim, reflected, f_reflected)
        elif f_reflected < fsim[dim - 1]:
            _set_vertex(sim, fsim, dim, reflected, f_reflected)
        else:  # contract, outside the simplex or inside
            inside = f_reflected >= fsim[dim]
            for k in range(dim):
                if inside:
                    trial[k] = 0.5 * centroid[k] + 0.5 * sim[dim, k]
                else:
                    trial[k] = 1.5 * centroid[k] - 0.5 * sim[dim, k]
            f_trial = reduced_energy_change(trial, tables, previous, v)
            evaluations += 1
            if f_trial < fsim[dim] if inside else f_trial <= f_reflected:
                _set_vertex(sim, fsim, dim, trial, f_trial)
            else:  # shrink towards the best vertex
                for j in range(1, npts):
                    for k in range(dim):
                        sim[j, k] = sim[0, k] + 0.5 * (sim[j, k] - sim[0, k])
                    fsim[j] = reduced_energy_change(sim[j], tables, previous, v)
                    evaluations += 1
        iterations += 1
        _order_vertices(sim, fsim)
    return sim[0].copy(), evaluations


@njit(**INTERNAL_LEAF)
def _set_vertex(sim, fsim, j, x, value):
    for k in range(len(x)):
        sim[j, k] = x[k]
    fsim[j] = value


@njit(**INTERNAL_LEAF)
def _spread(sim, fsim, of_vertices):
    """scipy's two convergence measures: the largest distance of a vertex from the
    best in any coordinate, or of a value from the best value (NaN if any is NaN)."""
    largest = 0.0
    for j in range(1, sim.shape[0]):
        for k in range(sim.shape[1] if of_vertices else 1):
            d = abs(sim[j, k] - sim[0, k]) if of_vertices else abs(fsim[0] - fsim[j])
            if d > largest or d != d:
                largest = d
    return largest


@njit(**INTERNAL_LEAF)
def _order_vertices(sim, fsim):
    """Vertices and values in place by value: a stable insertion sort, NaN after every
    number, which is numpy's argsort (scipy's) up to 3 vertices. From 4, numpy on an
    AVX-512 CPU sorts with a network that puts equal values in its own order, so there
    scipy's result depends on the CPU (in the last digits: ties come near convergence)
    and this one's does not."""
    for i in range(1, len(fsim)):
        j = i
        while j > 0 and _before(fsim[j], fsim[j - 1]):
            fsim[j], fsim[j - 1] = fsim[j - 1], fsim[j]
            for k in range(sim.shape[1]):
                sim[j, k], sim[j - 1, k] = sim[j - 1, k], sim[j, k]
            j -= 1


@njit(**INTERNAL_LEAF)
def _before(a, b):
    """numpy's order of floats: a < b, and every number before NaN."""
    return a < b or (b != b and a == a)
