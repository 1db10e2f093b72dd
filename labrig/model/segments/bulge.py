"""A segment whose tube bulges after its peak: the uniform curve with a Maxwell plateau.

The SI's tube (and ``ogden_braided``'s) deforms uniformly, so after its pressure peak it
softens slowly all the way to the braids (B46-T20: 2 kPa/mL at most). A latex tube
under volume control does not: past the peak it localises into a bulge, the pressure
falls within a few millilitres to the bulge's propagation pressure, and the bulge then
spreads along the tube at that pressure until the whole tube lies against the braids
(Chater and Hutchinson's two-phase tube; the SI names these bulges among its limits).

``bulging_curve`` builds that from the uniform curve p_u(v): the propagation pressure
p_M is Maxwell's, the equal-area pressure between the uniform branch before the peak
(v_a) and the stiffening branch after contact (v_b), int_{v_a}^{v_b} (p_u - p_M) dv = 0;
after the peak the pressure drops with a slope ``drop_kpa_per_ml`` to the plateau, which
runs to v_b falling by ``PLATEAU_FALL`` of the drop (a plateau exactly flat would leave
the falling branch without a strict order); from v_b on the curve is the uniform one.
On the plateau the tube is two uniform parts, a fraction (v - v_a)/(v_b - v_a) of it in
the bulged state, so its length is the mixture of the two states' lengths.
"""

from __future__ import annotations

import numpy as np
from scipy.optimize import brentq

from labrig.model.segments.curve import SegmentCurve

# the plateau falls by this fraction of the drop from the peak to it
PLATEAU_FALL = 0.05
DROP_SAMPLES = 9
PLATEAU_SAMPLES = 33


def maxwell_pressure(curve: SegmentCurve) -> tuple[float, float, float]:
    """(p_M, v_a, v_b): the equal-area pressure between the first and the last branch
    of a rise-fall-rise curve and the two volumes where the uniform curve has it."""
    first, last = 0, len(curve.branches) - 1
    peak, valley = curve.peak, curve.valley

    def volumes(p):
        return float(curve.volume_on_branch(first, p)[0]), float(curve.volume_on_branch(last, p)[0])

    def area(p):
        v_a, v_b = volumes(p)
        return float(curve.energy_mj(v_b) - curve.energy_mj(v_a)) - p * (v_b - v_a)

    p_m = brentq(area, valley.p_kpa, peak.p_kpa, xtol=1e-12)
    return (p_m, *volumes(p_m))


def bulging_curve(curve: SegmentCurve, drop_kpa_per_ml: float) -> SegmentCurve:
    """``curve`` with the bulge's drop and plateau between its peak and the stiffening
    branch (module docstring); a curve without a peak is returned as it is."""
    if not drop_kpa_per_ml > 0:
        raise ValueError(f"drop_kpa_per_ml must be > 0, got {drop_kpa_per_ml}")
    peak = curve.peak
    if peak is None:
        return curve
    p_m, v_a, v_b = maxwell_pressure(curve)
    fall = PLATEAU_FALL * (peak.p_kpa - p_m)
    p_drop_end = p_m + fall
    v_drop_end = peak.v_ml + (peak.p_kpa - p_drop_end) / drop_kpa_per_ml
    if not v_drop_end < v_b:
        v_drop_end = peak.v_ml + 0.5 * (v_b - peak.v_ml)  # a drop steeper than asked
    l_a, l_b = (float(x) for x in curve.length_mm(np.array([v_a, v_b])))

    def mixture_mm(v):
        return l_a + (v - v_a) / (v_b - v_a) * (l_b - l_a)

    v_drop = np.linspace(peak.v_ml, v_drop_end, DROP_SAMPLES)[1:]
    p_drop = np.linspace(peak.p_kpa, p_drop_end, DROP_SAMPLES)[1:]
    l_peak = float(curve.length_mm(peak.v_ml))
    l_drop = l_peak + (v_drop - peak.v_ml) / (v_drop_end - peak.v_ml) * (
        mixture_mm(v_drop_end) - l_peak
    )
    v_plateau = np.linspace(v_drop_end, v_b, PLATEAU_SAMPLES)[1:-1]
    p_plateau = p_drop_end - (v_plateau - v_drop_end) / (v_b - v_drop_end) * fall
    before = curve.v_ml <= peak.v_ml
    after = curve.v_ml > v_b
    v = np.concatenate([curve.v_ml[before], v_drop, v_plateau, [v_b], curve.v_ml[after]])
    p = np.concatenate([curve.p_kpa[before], p_drop, p_plateau, [p_m], curve.p_kpa[after]])
    length = np.concatenate(
        [curve.l_mm[before], l_drop, mixture_mm(v_plateau), [l_b], curve.l_mm[after]]
    )
    return SegmentCurve(
        curve.name,
        v,
        p,
        length,
        V0_ml=curve.V0_ml,
        source=(
            f"{curve.source}; bulging after the peak: propagation pressure {p_m:.2f} kPa "
            f"(Maxwell) from {v_a:.3f} to {v_b:.3f} mL, drop {drop_kpa_per_ml:g} kPa/mL"
        ),
    )
