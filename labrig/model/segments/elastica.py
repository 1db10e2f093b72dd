"""The braids as clamped-clamped elastic strips: the envelope they enclose at a length.

Each of the eight strips is cut from the braid tubing and stays in the tubing's uncut
rings at both ends, so it is clamped (zero slope) there. Pushed to an end-to-end length
l < L it buckles into the first symmetric mode of Euler's elastica. With the modulus k
(the sine of half the largest angle) and lambda = 4 K(k)/L:

- the shortening is (L - l)/L = 2 - 2 E(k)/K(k);
- at arc length s the strip stands (2k/lambda)(1 - cn(lambda s | k^2)) off its ends'
  radius, widest at mid-length, k L/K(k);
- its axial advance is dx = (2 dn^2 - 1) ds, so the solid of revolution it bounds is
  V = (pi/lambda) int_0^{4K} (a + (2k/lambda)(1 - cn u))^2 (2 dn^2 u - 1) du.

The shape at a given shortening does not depend on the strip's bending stiffness: the
force does ((2K/pi)^2 times the critical force), and the paper gives that force as a
constant (S31). At small shortening the strip is the cosine 1 - cos(2 pi x/L) of height
(2/pi) sqrt(L (L - l)); S40's two hinged bars reach sqrt(L (L - l)/2) at mid-length.

The middle part of the solid (``middle_part``; docs/decisions/0011: where a bulge lies
as it spreads from mid-length) is the same integral from the mid-point u = 2K out to
2K +- U on both sides: with t = 2K - u, cn(2K - t) = -cn t and dn(2K - t) = dn t, so its
radius is a + (2k/lambda)(1 + cn t), its axial span (2/lambda)(2 E(am U | m) - U) and
its volume (2 pi/lambda) int_0^U r(t)^2 (2 dn^2 t - 1) dt. At U = 2K it is the whole
solid.
"""

from __future__ import annotations

import numpy as np
from scipy.optimize import brentq
from scipy.special import ellipe, ellipeinc, ellipj, ellipk

# The modulus table: k^2 against the shortening, inverted by interpolation and one
# Newton step (shortening to ~1e-12). k up to 0.99: shortening 1.39, past l = 0.
_M_TABLE = np.linspace(0.0, 0.99, 4001) ** 2
_NODES, _WEIGHTS = np.polynomial.legendre.leggauss(64)


def shortening_of_modulus(m):
    """(L - l)/L of the clamped elastica of parameter m = k^2: 2 - 2 E(m)/K(m)."""
    m = np.asarray(m, dtype=float)
    return 2 - 2 * ellipe(m) / ellipk(m)


_S_TABLE = shortening_of_modulus(_M_TABLE)


def modulus_for_shortening(shortening):
    """m = k^2 of the clamped elastica shortened by ``shortening`` = (L - l)/L >= 0."""
    s = np.asarray(shortening, dtype=float)
    m = np.interp(s, _S_TABLE, _M_TABLE)
    # Newton on S(m): dS/dm = -2 (E' K - E K')/K^2 with K' = (E - (1-m)K)/(2m(1-m)),
    # E' = (E - K)/(2m); left alone below m = 1e-6, where S = m to 1e-6 relative.
    safe = np.maximum(m, 1e-6)
    big_k, big_e = ellipk(safe), ellipe(safe)
    d_k = (big_e - (1 - safe) * big_k) / (2 * safe * (1 - safe))
    d_e = (big_e - big_k) / (2 * safe)
    slope = -2 * (d_e * big_k - big_e * d_k) / big_k**2
    polished = safe - (shortening_of_modulus(safe) - s) / slope
    return np.where(m > 1e-6, polished, m)


def widest_radius_mm(length_mm, l_braid_mm: float, end_radius_mm: float):
    """The envelope's radius at mid-length, a + k L/K(k), for strips held at
    ``length_mm`` end to end (straight, a, at l >= L)."""
    shortening = np.maximum(1 - np.asarray(length_mm, dtype=float) / l_braid_mm, 0.0)
    m = modulus_for_shortening(shortening)
    return end_radius_mm + np.sqrt(m) * l_braid_mm / ellipk(m)


def envelope_volume_mm3(length_mm, l_braid_mm: float, end_radius_mm: float):
    """Volume the strips enclose at end-to-end length ``length_mm`` (module docstring),
    by 64-point Gauss-Legendre over half the strip, doubled by symmetry."""
    length = np.asarray(length_mm, dtype=float)
    shortening = np.maximum(1 - length / l_braid_mm, 0.0)
    m = modulus_for_shortening(shortening)[..., None]
    quarter = ellipk(m)  # K: u runs over [0, 2K] for half the strip
    lam = 4 * quarter / l_braid_mm
    u = quarter * (1 + _NODES)
    _, cn, dn, _ = ellipj(u, m)
    radius = end_radius_mm + 2 * np.sqrt(m) / lam * (1 - cn)
    integrand = radius**2 * (2 * dn**2 - 1)
    return 2 * np.pi / lam[..., 0] * quarter[..., 0] * np.sum(_WEIGHTS * integrand, axis=-1)


def _strip(length_mm: float, l_braid_mm: float):
    """(m, K(m), lambda) of strips held at ``length_mm`` end to end."""
    m = float(modulus_for_shortening(max(1 - length_mm / l_braid_mm, 0.0)))
    quarter = float(ellipk(m))
    return m, quarter, 4 * quarter / l_braid_mm


def _middle_span_mm(extent, m: float, lam: float):
    """Axial span of the strips between u = 2K - U and 2K + U (module docstring)."""
    phase = ellipj(extent, m)[3]
    return 2 / lam * (2 * ellipeinc(phase, m) - extent)


def middle_part(length_mm: float, span_mm: float, l_braid_mm: float, end_radius_mm: float):
    """(volume mm^3, radius at its two end sections mm) of the strips' solid of revolution
    between the two sections ``span_mm`` apart, symmetric about mid-length, for strips
    held at ``length_mm`` end to end. ``span_mm`` from 0 (volume 0, the widest radius) to
    ``length_mm`` (the whole solid, ``envelope_volume_mm3``, radius a)."""
    m, quarter, lam = _strip(length_mm, l_braid_mm)
    if span_mm >= length_mm:
        extent = 2 * quarter
    elif span_mm <= 0:
        extent = 0.0
    else:
        extent = brentq(
            lambda u: _middle_span_mm(u, m, lam) - span_mm, 0.0, 2 * quarter, xtol=1e-15
        )
    t = 0.5 * extent * (1 + _NODES)
    _, cn, dn, _ = ellipj(t, m)
    height = 2 * np.sqrt(m) / lam
    radius = end_radius_mm + height * (1 + cn)
    volume = 2 * np.pi / lam * 0.5 * extent * np.sum(_WEIGHTS * radius**2 * (2 * dn**2 - 1))
    front = end_radius_mm + height * (1 + float(ellipj(extent, m)[1]))
    return float(volume), float(front)
