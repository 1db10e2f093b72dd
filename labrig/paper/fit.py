"""The calibration of the library: the free constants fitted to the paper's peak range
and Movie S3, with scipy.optimize, nothing else.

The objective is dimensionless: every peak outside 66-84 kPa (1 kPa inside the paper's
65-85) adds its excess squared over (5 kPa)^2, a segment without a peak adds 36, a
spread under 12 kPa adds its shortfall squared over (2 kPa)^2; Movie S3 adds
((v_snap - 23 mL) / 3 mL)^2 for its snap that lengthens the actuator, plus 4 if the
nearest snap shortens it; without any snap, 16 plus the same term for the second peak
crossing (where the snap should be), so that the simplex still sees a slope. Bounded
Nelder-Mead: the objective has steps where a transition changes type, and a simplex
does not need its gradient.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from functools import cache

import numpy as np

from labrig.model.segments.calibrated import CALIBRATION, Calibration, calibrated_curve
from labrig.paper.statements import (
    MOVIE_S3,
    PEAK_RANGE_KPA,
    inflation_snaps,
    nearest,
    peak_pressures,
    second_peak_crossings,
)

FIELDS = (
    "shear_modulus_mpa",
    "ogden_alpha",
    "end_stiffening",
    "force_scale",
    "envelope_radius_mm",
    "contact_compliance",
    "depth_gain",
    "drop_width_ml",
)
BOUNDS = (
    (0.2, 1.5),
    (1.0, 2.0),
    (0.0, 15.0),
    (0.3, 1.5),
    (4.0, 7.94),
    (1.0, 20.0),
    (1.0, 10.0),
    (0.2, 5.0),
)
MARGIN_KPA = 1.0
S3_VOLUME_ML = 23.0


@dataclass(frozen=True)
class FitResult:
    calibration: Calibration
    objective: float
    evaluations: int
    start_objective: float


def library_of(calibration: Calibration) -> Callable:
    """name (``B46-T20``) -> the curve of the segment calibrated with ``calibration``."""

    @cache
    def build(name: str):
        braid, tube = name.removeprefix("B").split("-T")
        return calibrated_curve(float(braid), float(tube), name, calibration)

    return build


def objective(calibration: Calibration) -> float:
    """The calibration subset's misfit (module docstring); inf where a segment cannot
    be built with these constants."""
    try:
        library = library_of(calibration)
        peaks = peak_pressures(library)
        snaps = inflation_snaps(library, MOVIE_S3)
        crossings = [] if snaps else second_peak_crossings(library, MOVIE_S3)
    except (ValueError, ArithmeticError, RuntimeError):
        return float("inf")
    values = np.array([p for p in peaks.values() if p is not None])
    low, high = PEAK_RANGE_KPA[0] + MARGIN_KPA, PEAK_RANGE_KPA[1] - MARGIN_KPA
    misfit = float(np.sum(np.maximum(low - values, 0) ** 2 + np.maximum(values - high, 0) ** 2))
    total = misfit / 25 + 36 * (36 - len(values))
    spread = float(values.max() - values.min()) if len(values) else 0.0
    total += max(0.0, 12.0 - spread) ** 2 / 4
    lengthening = [s for s in snaps if s.dl > 0]
    snap = nearest(lengthening, S3_VOLUME_ML) or nearest(snaps, S3_VOLUME_ML)
    if snap is None:
        misses = [((v - S3_VOLUME_ML) / 3.0) ** 2 for v in crossings]
        return total + 16.0 + min(misses, default=16.0)
    total += ((snap.v_ml - S3_VOLUME_ML) / 3.0) ** 2
    return total + (0.0 if snap.dl > 0 else 4.0)


def _calibration(x) -> Calibration:
    clipped = [min(max(float(v), lo), hi) for v, (lo, hi) in zip(x, BOUNDS, strict=True)]
    return Calibration(**dict(zip(FIELDS, clipped, strict=True)))


def fit(start: Calibration = CALIBRATION, max_evaluations: int = 120, progress=None) -> FitResult:
    """Minimise ``objective`` from ``start`` (bounded Nelder-Mead)."""
    from scipy.optimize import minimize

    x0 = [getattr(start, f) for f in FIELDS]
    evaluated: list[tuple[np.ndarray, float]] = []  # the first: Nelder-Mead starts at x0

    def f(x):
        value = objective(_calibration(x))
        if not evaluated:
            evaluated.append((np.array(x, dtype=float), value))
        if progress is not None:
            progress(_calibration(x), value)
        return value

    found = minimize(
        f,
        x0,
        method="Nelder-Mead",
        bounds=BOUNDS,
        options={"maxfev": max_evaluations, "xatol": 1e-3, "fatol": 1e-3, "initial_simplex": None},
    )
    # One objective costs seconds: the start's value is the first evaluation's, computed
    # again only if the optimiser began elsewhere.
    if evaluated and np.array_equal(evaluated[0][0], np.asarray(x0, dtype=float)):
        start_objective = evaluated[0][1]
    else:
        start_objective = objective(_calibration(x0))
    return FitResult(_calibration(found.x), float(found.fun), int(found.nfev), start_objective)
