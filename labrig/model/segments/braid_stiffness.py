"""The braids' own radial give once the tube lies against them.

The braided segments treat the braids as inextensible after contact, so the pressure on
the stiffening branch can rise by hundreds of kPa within 1e-4 mL (a bulge plateau that
ends below the contact pressure makes that a wall). Real braids are fibres wound at an
angle: they stretch and open, so after contact the tube and the braids act as two
springs in series. ``with_braid_stiffness`` adds the braids' spring, of stiffness
``k_kpa_per_ml``, to every sample past the valley: a sample at pressure p moves to a
larger volume by (p - p_valley) / k. A wall becomes a slope k, a slope s becomes
1 / (1/s + 1/k), and the braids take the work (p^2 - p_valley^2) / 2k.
"""

from __future__ import annotations

import numpy as np

from labrig.model.segments.curve import SegmentCurve


def with_braid_stiffness(curve: SegmentCurve, k_kpa_per_ml: float) -> SegmentCurve:
    """``curve`` with a spring of ``k_kpa_per_ml`` in series after its valley; a curve
    without a valley is returned as it is."""
    if not k_kpa_per_ml > 0:
        raise ValueError(f"k_kpa_per_ml must be > 0, got {k_kpa_per_ml}")
    valley = curve.valley
    if valley is None:
        return curve
    after = curve.v_ml > valley.v_ml
    v = curve.v_ml.copy()
    v[after] += np.maximum(curve.p_kpa[after] - valley.p_kpa, 0.0) / k_kpa_per_ml
    return SegmentCurve(
        curve.name,
        v,
        curve.p_kpa,
        curve.l_mm,
        V0_ml=curve.V0_ml,
        source=f"{curve.source}; braids of {k_kpa_per_ml:g} kPa/mL in series after contact",
        measured=curve.measured,
    )
