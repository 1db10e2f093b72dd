"""Stored energy read off a pressure-volume curve, for the measurement and the model alike.

The model's stored energy E is the sum of the segments' ∫ p_i dv_i from the
unpressurised state; along a stable path dE/dv = p, so up to the first snap E is the
pump's work ∫ p dv along the actuator's own curve (kPa·mL = mJ). A snap at constant
volume releases E_before - E_after, the model's dE = (E_after - E_before)/E_before.

A measured p-v cycle cannot split that release between the snaps of one loop: the
inflation curve gives E_before of its first snap exactly, but the state a snap lands
on is only seen again on the way down, which releases energy in its own snap before it
reaches 0 mL. What the cycle does give is the energy deflation returns from the snap's
volume, ∫_0^v p_deflate dv; ``cycle_dE`` = (that - E_before)/E_before is the fraction of
the stored energy the loop left of v dissipates: the snap's release plus the release of
the deflation snap that closes the loop (equal to the model's dE where the way down
releases nothing). The same number is computed on the model's curves, so measurement
and model are compared on one definition, beside the model's own dE.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from labrig.analysis.results import AnalysisResult


def stored_energy_mj(v_ml: np.ndarray, p_kpa: np.ndarray, upto_ml: float) -> float:
    """∫ p dv (mJ) from the curve's first point to ``upto_ml`` by the trapezoid rule,
    the end interpolated; NaN outside the volumes the curve covers.

    ``v_ml`` must not decrease (a snap is two points at one volume, in the order they
    happen); NaN points are left out."""
    v, p = np.asarray(v_ml, dtype=float), np.asarray(p_kpa, dtype=float)
    finite = np.isfinite(v) & np.isfinite(p)
    v, p = v[finite], p[finite]
    if len(v) < 2 or not v[0] <= upto_ml <= v[-1]:
        return float("nan")
    k = int(np.searchsorted(v, upto_ml, side="left"))  # first point at or past upto_ml
    if v[k] == upto_ml:
        p_end = p[k]
    else:
        p_end = p[k - 1] + (p[k] - p[k - 1]) * (upto_ml - v[k - 1]) / (v[k] - v[k - 1])
    return float(np.trapezoid(np.append(p[:k], p_end), np.append(v[:k], upto_ml)))


def cycle_dE(
    v_inflate_ml: np.ndarray,
    p_inflate_kpa: np.ndarray,
    v_deflate_ml: np.ndarray,
    p_deflate_kpa: np.ndarray,
    at_ml: float,
) -> tuple[float, float, float]:
    """(E_before, E_returned, their relative change) at ``at_ml`` of one cycle: the
    inflation's work to ``at_ml``, the work deflation returns from there to the start
    (both curves with increasing volume), and (E_returned - E_before)/E_before (module
    docstring); NaN where a curve does not reach ``at_ml``."""
    before = stored_energy_mj(v_inflate_ml, p_inflate_kpa, at_ml)
    after = stored_energy_mj(v_deflate_ml, p_deflate_kpa, at_ml)
    if not (np.isfinite(before) and np.isfinite(after) and before > 0):
        return before, after, float("nan")
    return before, after, (after - before) / before


def released_mj(
    v_inflate_ml: np.ndarray,
    p_inflate_kpa: np.ndarray,
    v_deflate_ml: np.ndarray,
    p_deflate_kpa: np.ndarray,
) -> float:
    """The energy a whole cycle dissipates (mJ): the area between its inflation and
    deflation curves over the volumes both cover (NaN without both)."""
    top = min(_top(v_inflate_ml, p_inflate_kpa), _top(v_deflate_ml, p_deflate_kpa))
    if not np.isfinite(top):
        return float("nan")
    return stored_energy_mj(v_inflate_ml, p_inflate_kpa, top) - stored_energy_mj(
        v_deflate_ml, p_deflate_kpa, top
    )


def _top(v_ml: np.ndarray, p_kpa: np.ndarray) -> float:
    finite = np.isfinite(np.asarray(v_ml, dtype=float)) & np.isfinite(np.asarray(p_kpa))
    return float(np.max(np.asarray(v_ml)[finite])) if np.count_nonzero(finite) >= 2 else np.nan


def finite_or_none(value: float | None) -> float | None:
    """A number for JSON: NaN, infinities and missing become null."""
    if value is None or not np.isfinite(value):
        return None
    return float(value)


def _curves(result: AnalysisResult) -> tuple[tuple, tuple] | None:
    """(measured, model) cycles as (v_in, p_in, v_out, p_out), or None without both."""
    from labrig.analysis.curves import DEFLATE, INFLATE

    if result.comparison is None or result.mean_p is None:
        return None
    grid, mean = result.grid_ml, result.mean_p
    prediction = result.comparison.prediction
    measured = (grid, mean[INFLATE].mean, grid, mean[DEFLATE].mean)
    return measured, (*prediction.phase_curve(INFLATE), *prediction.phase_curve(DEFLATE))


def transition_energy(result: AnalysisResult, predicted, measured) -> dict[str, float | None]:
    """A compared transition's energies (``compare --json``'s row fields): the model's
    E before and after and its dE; for an inflation transition, the one-cycle numbers
    (``cycle_dE``) of the measurement at its volume and of the model at its own."""
    row: dict[str, float | None] = {
        "energy_before_model_mj": finite_or_none(predicted.energy_before_mj) if predicted else None,
        "energy_after_model_mj": finite_or_none(predicted.energy_after_mj) if predicted else None,
        "dE_model": finite_or_none(predicted.dE) if predicted else None,
    }
    curves = _curves(result)
    for side, transition, cycle in (
        ("measured", measured, curves[0] if curves else None),
        ("model", predicted, curves[1] if curves else None),
    ):
        numbers = (float("nan"),) * 3
        if transition is not None and cycle is not None and transition.direction > 0:
            numbers = cycle_dE(*cycle, transition.v_ml)
        row[f"cycle_energy_before_{side}_mj"] = finite_or_none(numbers[0])
        row[f"cycle_energy_returned_{side}_mj"] = finite_or_none(numbers[1])
        row[f"cycle_dE_{side}"] = finite_or_none(numbers[2])
    return row


def cycle_energy(result: AnalysisResult) -> dict[str, float | None]:
    """The run's cycle (``compare --json``'s ``energy``): the energy stored at the top
    of the mean inflation and what the cycle dissipates (the loop's area), measured and
    model, and the model's releases summed over its snaps (equal to its loop's area)."""
    curves = _curves(result)
    out: dict[str, float | None] = {}
    for side, cycle in zip(("measured", "model"), curves or (None, None), strict=True):
        top = _top(cycle[0], cycle[1]) if cycle else float("nan")
        stored = stored_energy_mj(cycle[0], cycle[1], top) if cycle else float("nan")
        out[f"stored_{side}_mj"] = finite_or_none(stored)
        out[f"released_{side}_mj"] = finite_or_none(released_mj(*cycle) if cycle else float("nan"))
    snaps = (
        [t for t in result.comparison.prediction.transitions if not t.stable]
        if result.comparison is not None
        else []
    )
    out["released_by_snaps_model_mj"] = finite_or_none(
        float(sum(t.energy_before_mj - t.energy_after_mj for t in snaps))
    )
    return out
