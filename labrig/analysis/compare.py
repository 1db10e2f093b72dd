"""The measurement against the stability model: predicted curves, RMSE, transitions.

The prediction is the model's quasi-static path for the specimen's segments (analytical
library segments, or measured segments from earlier single-segment runs, as the paper
does), inflated to the largest volume the run reached and, if the run withdrew, deflated
back. The actuator's length is the sum of the segment lengths plus the fittings between
the markers. A single segment needs no path solver: under volume control it follows its
own curve both ways.

The comparison is made on the analysis grid, per phase (inflation, deflation): the RMSE
of pressure and length between the averaged measurement and the prediction where both
exist, and the predicted snap-throughs paired with the measured transitions (same
direction, nearest volume within ``match_ml``). Predicted stable transitions (a segment
crossing its peak smoothly) are listed but not paired: nothing jumps there. The pairing
is made twice: for the path's events (``matches``: every peak crossing and every snap,
what the run file's analysis stores) and for the transitions as the paper counts them
(``paper_matches``: the events at one supplied volume are one,
``labrig.model.actuator.paper_counting``), which the report, its ``unpredicted`` list
and the plots' diamonds use. A measured
transition that no predicted snap explains may still be on the model's curve: a steep
stable stretch (a bulge's drop, taken while the other segments absorb the volume, or
the braids' wall) changes the pressure within a millilitre, which the detector sees as a
snap; ``follows_model`` tells those apart from transitions the model lacks.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from labrig.analysis.curves import DEFLATE, INFLATE, PHASES
from labrig.analysis.transitions import AgreedTransition
from labrig.errors import LabrigError
from labrig.model.actuator.paper_counting import EVENT_FIELDS, paper_transitions
from labrig.model.segments.curve import SegmentCurve

SAMPLE_DV_ML = 0.05
# around a measured transition, how far the model's curve must follow the measurement
ON_CURVE_WINDOW_ML = 1.0


@dataclass(frozen=True)
class PredictedTransition:
    """A transition on the model's path: the model's own numbers (v_ml, alpha, beta,
    stable, the normalised dE, dv, dl, dp), the jump in physical units and the stored
    energy on both sides of it (mJ; NaN in a run file analysed before they were kept)."""

    direction: int
    v_ml: float
    alpha: int
    beta: int
    stable: bool
    dE: float
    dv: float
    dl: float
    dp: float
    dp_kpa: float
    dl_mm: float
    energy_before_mj: float = math.nan
    energy_after_mj: float = math.nan

    @property
    def type(self) -> str:
        return f"{'stable' if self.stable else 'snap'} ({self.alpha},{self.beta})"


def paper_counted(predicted: Sequence[PredictedTransition]) -> tuple[PredictedTransition, ...]:
    """The path's events ``predicted`` counted as the paper counts transitions
    (``paper_transitions``); the jumps in kPa and mm of events at one volume add (the
    relative ones compound)."""
    return tuple(
        PredictedTransition(
            **{name: getattr(t, name) for name in EVENT_FIELDS},
            dp_kpa=math.fsum(e.dp_kpa for e in t.events),
            dl_mm=math.fsum(e.dl_mm for e in t.events),
            energy_before_mj=t.events[0].energy_before_mj,
            energy_after_mj=t.events[-1].energy_after_mj,
        )
        for t in paper_transitions(predicted)
    )


@dataclass(frozen=True)
class Prediction:
    """The model's path as arrays (a snap is two points at one volume) and its
    transitions. ``direction`` is +1 on inflation, -1 on deflation."""

    segments: tuple[str, ...]
    sources: tuple[str, ...]
    v_ml: np.ndarray
    p_kpa: np.ndarray
    l_mm: np.ndarray
    direction: np.ndarray
    transitions: tuple[PredictedTransition, ...]

    def phase_curve(self, phase: int) -> tuple[np.ndarray, np.ndarray]:
        """The path's (volume, pressure) of ``phase`` with the volume increasing (a
        snap's two points kept in the order they happen on the way up)."""
        chosen = self.direction == phase
        v, p = self.v_ml[chosen], self.p_kpa[chosen]
        return (v, p) if phase == INFLATE else (v[::-1], p[::-1])

    def on_grid(self, grid_ml: np.ndarray, phase: int, quantity: str) -> np.ndarray:
        """``quantity`` ("p" or "l") of the path's ``phase`` on the grid; NaN outside
        the volumes the path covers."""
        chosen = self.direction == phase
        v = self.v_ml[chosen]
        y = (self.p_kpa if quantity == "p" else self.l_mm)[chosen]
        out = np.full(len(grid_ml), np.nan)
        if len(v) < 2:
            return out
        order = np.argsort(v, kind="stable")
        v, y = v[order], y[order]
        inside = (grid_ml >= v[0]) & (grid_ml <= v[-1])
        out[inside] = np.interp(grid_ml[inside], v, y)
        return out


def predict(
    curves: Sequence[SegmentCurve],
    fittings_length_mm: float,
    v_max_ml: float,
    deflate: bool,
) -> Prediction:
    """The model's path for these segments up to ``v_max_ml`` (and back if ``deflate``)."""
    names = tuple(curve.name for curve in curves)
    sources = tuple(curve.source for curve in curves)
    if len(curves) == 1:
        return _single_segment(curves[0], fittings_length_mm, v_max_ml, deflate, names, sources)
    from labrig.model.actuator.descent import FlowError
    from labrig.model.actuator.equilibria import Actuator
    from labrig.model.actuator.path import quasi_static_path, sample_path
    from labrig.model.actuator.transitions import transitions

    actuator = Actuator(list(curves))
    try:
        path = quasi_static_path(actuator, v_max_ml, deflate=deflate)
    except FlowError as exc:
        raise LabrigError(f"the model's path of {' + '.join(names)} failed: {exc}") from None
    sampled = sample_path(path, SAMPLE_DV_ML)
    predicted = tuple(
        PredictedTransition(
            direction=int(t.direction),
            v_ml=float(t.v_ml),
            alpha=int(t.alpha),
            beta=int(t.beta),
            stable=bool(t.stable),
            dE=float(t.dE),
            dv=float(t.dv),
            dl=float(t.dl),
            dp=float(t.dp),
            dp_kpa=float(t.post.p_kpa - t.pre.p_kpa),
            dl_mm=float(actuator.length_mm(t.post.v_i_ml) - actuator.length_mm(t.pre.v_i_ml)),
            energy_before_mj=float(actuator.energy_mj(t.pre.v_i_ml)),
            energy_after_mj=float(actuator.energy_mj(t.post.v_i_ml)),
        )
        for t in transitions(path)
    )
    return Prediction(
        names,
        sources,
        np.asarray(sampled.v_ml, dtype=float),
        np.asarray(sampled.p_kpa, dtype=float),
        np.asarray(sampled.l_mm, dtype=float) + fittings_length_mm,
        np.asarray(sampled.direction, dtype=int),
        predicted,
    )


def _single_segment(curve, fittings_length_mm, v_max_ml, deflate, names, sources) -> Prediction:
    from labrig.model.actuator.prediction import predicted_inflation

    v, p, length = predicted_inflation([curve], v_max_ml, SAMPLE_DV_ML)
    # under volume control a lone segment runs back down its own curve
    phases = [(v, p, length, INFLATE)] + (
        [(v[::-1], p[::-1], length[::-1], DEFLATE)] if deflate else []
    )
    return Prediction(
        names,
        sources,
        np.concatenate([x[0] for x in phases]),
        np.concatenate([x[1] for x in phases]).astype(float),
        np.concatenate([x[2] for x in phases]).astype(float) + fittings_length_mm,
        np.concatenate([np.full(len(x[0]), x[3]) for x in phases]),
        (),
    )


@dataclass(frozen=True)
class TransitionMatch:
    """A predicted snap with the measured transition paired to it, or either alone."""

    direction: int
    predicted: PredictedTransition | None
    measured: AgreedTransition | None

    @property
    def dv_ml(self) -> float:
        """Measured minus predicted volume (NaN unless both exist)."""
        if self.predicted is None or self.measured is None:
            return float("nan")
        return self.measured.v_ml - self.predicted.v_ml


@dataclass(frozen=True)
class Comparison:
    prediction: Prediction
    model_p_kpa: dict[int, np.ndarray]  # on the grid, per phase
    model_l_mm: dict[int, np.ndarray]
    rmse_p_kpa: dict[int, float]  # NaN where the phase has no overlap
    rmse_l_mm: dict[int, float]
    matches: tuple[TransitionMatch, ...]  # the path's events
    match_ml: float
    paper_matches: tuple[TransitionMatch, ...] = ()  # as the paper counts transitions


def rmse(measured: np.ndarray, model: np.ndarray) -> float:
    """Root-mean-square difference over the points where both exist (NaN if none)."""
    both = np.isfinite(measured) & np.isfinite(model)
    if not np.any(both):
        return float("nan")
    return float(np.sqrt(np.mean((measured[both] - model[both]) ** 2)))


def match_transitions(
    predicted: Sequence[PredictedTransition],
    measured: Sequence[AgreedTransition],
    match_ml: float,
) -> tuple[TransitionMatch, ...]:
    """Pair predicted snaps with measured transitions of the same direction, closest
    pairs first, each used once, at most ``match_ml`` apart; list the rest alone."""
    snaps = [t for t in predicted if not t.stable]
    pairs = sorted(
        (abs(m.v_ml - p.v_ml), i, j)
        for i, p in enumerate(snaps)
        for j, m in enumerate(measured)
        if m.direction == p.direction and abs(m.v_ml - p.v_ml) <= match_ml
    )
    used_p: dict[int, int] = {}
    used_m: set[int] = set()
    for _, i, j in pairs:
        if i not in used_p and j not in used_m:
            used_p[i] = j
            used_m.add(j)
    rows = [TransitionMatch(p.direction, p, None) for p in predicted if p.stable]
    rows += [
        TransitionMatch(p.direction, p, measured[used_p[i]] if i in used_p else None)
        for i, p in enumerate(snaps)
    ]
    rows += [
        TransitionMatch(m.direction, None, m) for j, m in enumerate(measured) if j not in used_m
    ]

    def key(row: TransitionMatch) -> tuple[int, float]:
        v = row.predicted.v_ml if row.predicted is not None else row.measured.v_ml
        return (-row.direction, row.direction * v)

    return tuple(sorted(rows, key=key))


def compare(
    prediction: Prediction,
    grid_ml: np.ndarray,
    mean_p_kpa: dict[int, np.ndarray],
    mean_l_mm: dict[int, np.ndarray] | None,
    measured: Sequence[AgreedTransition],
    match_ml: float = 2.0,
) -> Comparison:
    """The comparison of the averaged measurement with ``prediction`` on the grid."""
    model_p = {phase: prediction.on_grid(grid_ml, phase, "p") for phase in PHASES}
    model_l = {phase: prediction.on_grid(grid_ml, phase, "l") for phase in PHASES}
    rmse_p = {phase: rmse(mean_p_kpa[phase], model_p[phase]) for phase in PHASES}
    rmse_l = {
        phase: rmse(mean_l_mm[phase], model_l[phase]) if mean_l_mm is not None else float("nan")
        for phase in PHASES
    }
    return Comparison(
        prediction,
        model_p,
        model_l,
        rmse_p,
        rmse_l,
        match_transitions(prediction.transitions, measured, match_ml),
        match_ml,
        match_transitions(paper_counted(prediction.transitions), measured, match_ml),
    )


def follows_model(
    comparison: Comparison,
    grid_ml: np.ndarray,
    mean_p_kpa: dict[int, np.ndarray],
    measured: AgreedTransition,
) -> bool:
    """Whether the model's own curve makes ``measured``: within ``ON_CURVE_WINDOW_ML``
    of it the model changes by at least half of the measured step and the mean
    measurement stays within a quarter of the step of the model."""
    phase = INFLATE if measured.direction > 0 else DEFLATE
    near = np.abs(grid_ml - measured.v_ml) <= ON_CURVE_WINDOW_ML
    model, mean = comparison.model_p_kpa[phase][near], mean_p_kpa[phase][near]
    both = np.isfinite(model) & np.isfinite(mean)
    step = abs(measured.dp_kpa)
    if not (np.count_nonzero(both) >= 3 and step > 0):
        return False
    changes = np.ptp(model[both]) >= 0.5 * step
    return bool(changes and np.max(np.abs(mean[both] - model[both])) <= 0.25 * step)
