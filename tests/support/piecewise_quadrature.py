"""The integral of a segment's p(v) by Gauss-Legendre quadrature on each piece of its
table: a check of the curve's energy independent of its antiderivative.

PCHIP is a cubic between two knots and the curve is linear past its ends, so three Gauss
points a piece (exact to degree five) give the integral to rounding, where adaptive
quadrature over the whole range meets a kink at every knot and stops at its subdivision
limit with a warning.
"""

import numpy as np

from labrig.model.segments.curve import SegmentCurve

_NODES, _WEIGHTS = np.polynomial.legendre.leggauss(3)


def integral_of_pressure(curve: SegmentCurve, v_from_ml: float, v_to_ml: float) -> float:
    """∫ p dv from ``v_from_ml`` to ``v_to_ml`` (kPa·mL, = mJ), ``v_from_ml <= v_to_ml``."""
    knots = curve.v_ml[(curve.v_ml > v_from_ml) & (curve.v_ml < v_to_ml)]
    edges = np.concatenate([[v_from_ml], knots, [v_to_ml]])
    left, right = edges[:-1], edges[1:]
    half = (right - left) / 2
    at = (left + right)[:, None] / 2 + half[:, None] * _NODES[None, :]
    pressure_kpa = np.asarray(curve.pressure_kpa(at.ravel())).reshape(at.shape)
    return float(np.sum(half * (pressure_kpa @ _WEIGHTS)))
