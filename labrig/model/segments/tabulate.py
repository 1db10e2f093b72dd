"""Turn a parametric closed-form curve t -> (v, p, l) into a table PCHIP reproduces.

Analytical segment sources (braided tube, Gent sphere) know p and l exactly as functions
of a geometric parameter (a stretch or a braid angle), not of the supplied volume. A
``SegmentCurve`` needs a table in v that its PCHIP interpolant reproduces; a uniform
grid wastes samples on the smooth parts and under-samples the peak, the contact kink and
the stiffening wall. So the table is refined where it matters: an interval is split
when PCHIP through the current samples misses the exact value at the interval's
parametric midpoint by more than the tolerance. Points that must be samples (peak,
contact kink) are given as knots, so extrema sit exactly on samples.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

Evaluate = Callable[[np.ndarray], tuple[np.ndarray, np.ndarray, np.ndarray]]

# Interpolation error allowed between samples: far below any pressure difference the
# model resolves (sensor quantisation is 0.3 kPa, the shallowest analytical dip 0.007 kPa).
P_TOL_KPA = 1e-3
P_REL_TOL = 1e-5
L_TOL_MM = 1e-3


def tabulate(
    evaluate: Evaluate,
    knots: np.ndarray,
    *,
    p_tol_kpa: float = P_TOL_KPA,
    p_rel_tol: float = P_REL_TOL,
    l_tol_mm: float = L_TOL_MM,
    max_rounds: int = 30,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Sample ``evaluate`` (vectorised t -> (v_ml, p_kpa, l_mm), v increasing in t) from
    the sorted ``knots`` until PCHIP in v is within tolerance at every interval's
    parametric midpoint. Returns (t, v_ml, p_kpa, l_mm)."""
    # here, not at the top: a run reads its segments' tables from the cache, and
    # importing this module (through gent.py) must not cost it scipy's interpolation
    from scipy.interpolate import PchipInterpolator

    t = np.asarray(knots, dtype=float)
    v, p, length = evaluate(t)
    for _ in range(max_rounds):
        t_mid = 0.5 * (t[:-1] + t[1:])
        v_mid, p_mid, l_mid = evaluate(t_mid)
        p_err = np.abs(PchipInterpolator(v, p)(v_mid) - p_mid)
        l_err = np.abs(PchipInterpolator(v, length)(v_mid) - l_mid)
        bad = (p_err > p_tol_kpa + p_rel_tol * np.abs(p_mid)) | (l_err > l_tol_mm)
        if not bad.any():
            return t, v, p, length
        order = np.argsort(np.concatenate([t, t_mid[bad]]), kind="stable")
        t = np.concatenate([t, t_mid[bad]])[order]
        v = np.concatenate([v, v_mid[bad]])[order]
        p = np.concatenate([p, p_mid[bad]])[order]
        length = np.concatenate([length, l_mid[bad]])[order]
    raise RuntimeError(f"tabulation did not converge in {max_rounds} rounds ({len(t)} samples)")
