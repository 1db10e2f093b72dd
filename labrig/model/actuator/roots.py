"""A bracketed scalar root (Brent-Dekker), compiled, for the path solver's inner loops.

scipy's ``brentq`` does the same in C but needs finite values at both ends and costs a
few tens of microseconds per call in overhead; here an infinite end value (the slope
term 1/k at a branch end where k = 0) is allowed and only its sign is used. The
function whose root is sought is one of the compiled ``labrig.model.actuator.curve_tables``
objectives (``excess_volume_at``, ``inverse_slope_sum_at``, ``pair_imbalance``), named by
its number, so a whole root search runs without returning to Python.
"""

from __future__ import annotations

import math

from labrig.model.actuator.curve_tables import objective
from labrig.model.actuator.jit import LEAF, njit

# absolute and relative tolerances on a root (added), and the most iterations
XTOL = 1e-12
RTOL = 4e-16
MAX_ITER = 200


@njit(**LEAF)
def bracketed_root(kind, tables, branches, v, a, b, fa, fb, xtol):
    """A root of f(x) = ``objective(kind, x, tables, branches, v)`` between ``a`` and
    ``b``, where f changes sign (or is zero); ``fa``, ``fb`` are f at the ends, NaN to
    have them computed.

    ``xtol`` is an absolute tolerance on the root (``XTOL`` usually), added to ``RTOL``
    times its size. Raises ValueError without a sign change. Every argument is
    required: numba calls a compiled function with omitted arguments through a slow
    path (~50 us), longer than the search itself.
    """
    if math.isnan(fa):
        fa = objective(kind, a, tables, branches, v)
    if math.isnan(fb):
        fb = objective(kind, b, tables, branches, v)
    if fa == 0.0:
        return a
    if fb == 0.0:
        return b
    if (fa > 0) == (fb > 0):
        raise ValueError("no sign change between the ends of the bracket")
    c, fc = a, fa
    d = e = b - a
    for _ in range(MAX_ITER):
        if (fb > 0) == (fc > 0):
            c, fc = a, fa
            d = e = b - a
        if abs(fc) < abs(fb) or math.isinf(fb):
            a, b, c = b, c, b
            fa, fb, fc = fb, fc, fb
        tol = 2.0 * RTOL * abs(b) + 0.5 * xtol
        m = 0.5 * (c - b)
        if abs(m) <= tol or fb == 0.0:
            return b
        interpolate = (
            abs(e) >= tol and abs(fa) > abs(fb) and math.isfinite(fa) and math.isfinite(fc)
        )
        if interpolate:
            s = fb / fa
            if a == c:  # secant
                p = 2.0 * m * s
                q = 1.0 - s
            else:  # inverse quadratic
                q = fa / fc
                r = fb / fc
                p = s * (2.0 * m * q * (q - r) - (b - a) * (r - 1.0))
                q = (q - 1.0) * (r - 1.0) * (s - 1.0)
            if p > 0:
                q = -q
            else:
                p = -p
            if 2.0 * p < min(3.0 * m * q - abs(tol * q), abs(e * q)):
                e, d = d, p / q
            else:
                d = e = m
        else:
            d = e = m
        a, fa = b, fb
        b += d if abs(d) > tol else math.copysign(tol, m)
        fb = objective(kind, b, tables, branches, v)
    return b
