"""A segment whose tube bulges after its peak: the uniform curve with a bulge plateau.

The SI's tube (and ``ogden_braided``'s) deforms uniformly, so after its pressure peak it
softens slowly all the way to the braids (B46-T20: 2 kPa/mL at most). A latex tube
under volume control does not: past the peak it localises into a bulge, the pressure
falls within a millilitre or two, and the bulge then spreads along the tube at a nearly
constant propagation pressure until the whole tube lies against the braids (Chater and
Hutchinson's two-phase tube; the SI names these bulges among its limits).

``bulging_curve`` builds that from the uniform curve p_u(v):

- the plateau lies ``depth_gain`` times Maxwell's depth below the peak,
  p_plateau = p_peak - g (p_peak - p_M), with p_M the equal-area pressure between the
  uniform branch before the peak and the stiffening branch after contact. For g = 1 it
  is Maxwell's propagation pressure of a free tube; the clamped couplings and the braids'
  pull on a short bulge make the measured drop deeper (the paper's Fig. 1C falls by
  20-40 kPa where Maxwell's construction gives a few), and scaling Maxwell's depth keeps
  its ordering: deeper for long braids and short tubes;
- from the peak the pressure falls over ``drop_width_ml`` as a half cosine (no kink at
  either end, so the peak stays a smooth maximum);
- the plateau then falls by ``PLATEAU_FALL_KPA`` (at most the drop's depth) until it
  meets the stiffening branch; a plateau exactly flat would leave the falling branch
  without a strict order. Where the plateau lies below the stiffening branch's start it
  ends there, and the tube's contact with the braids is what lifts the pressure again.

On the plateau the tube is two uniform parts, the unbulged one on the rising branch at
the plateau's pressure and the bulged one where the plateau ends, so its length is the
mixture of the two states' lengths.
"""

from __future__ import annotations

import numpy as np
from scipy.optimize import brentq

from labrig.model.segments.curve import SegmentCurve

# how far the plateau falls to where it meets the braids
PLATEAU_FALL_KPA = 1.0
DROP_SAMPLES = 17
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


def plateau_pressure(curve: SegmentCurve, depth_gain: float) -> float:
    """The bulge's plateau: ``depth_gain`` times Maxwell's depth below the peak."""
    p_m, _, _ = maxwell_pressure(curve)
    peak = curve.peak.p_kpa
    plateau = peak - depth_gain * (peak - p_m)
    if not plateau > 0:
        raise ValueError(
            f"{curve.name}: a depth gain of {depth_gain:g} puts the plateau at "
            f"{plateau:.1f} kPa, below zero"
        )
    return plateau


def bulging_curve(curve: SegmentCurve, depth_gain: float, drop_width_ml: float) -> SegmentCurve:
    """``curve`` with the bulge's drop and plateau between its peak and the stiffening
    branch (module docstring); a curve without a peak is returned as it is."""
    if not depth_gain > 0:
        raise ValueError(f"depth_gain must be > 0, got {depth_gain}")
    if not drop_width_ml > 0:
        raise ValueError(f"drop_width_ml must be > 0, got {drop_width_ml}")
    peak, valley = curve.peak, curve.valley
    if peak is None:
        return curve
    p_top = plateau_pressure(curve, depth_gain)
    p_end = p_top - min(PLATEAU_FALL_KPA, peak.p_kpa - p_top)
    # where the plateau meets the stiffening branch, or where contact begins
    last = len(curve.branches) - 1
    on_braids = p_end > valley.p_kpa
    v_b = float(curve.volume_on_branch(last, p_end)[0]) if on_braids else valley.v_ml
    v_a = float(curve.volume_on_branch(0, p_top)[0])
    drop_end = peak.v_ml + min(drop_width_ml, 0.5 * (v_b - peak.v_ml))
    l_a, l_b = (float(x) for x in curve.length_mm(np.array([v_a, v_b])))

    def mixture_mm(v):
        return l_a + (v - v_a) / (v_b - v_a) * (l_b - l_a)

    s = np.linspace(0.0, 1.0, DROP_SAMPLES)[1:]
    v_drop = peak.v_ml + s * (drop_end - peak.v_ml)
    p_drop = p_top + (peak.p_kpa - p_top) * 0.5 * (1 + np.cos(np.pi * s))
    l_peak = float(curve.length_mm(peak.v_ml))
    l_drop = l_peak + s * (mixture_mm(drop_end) - l_peak)
    v_plateau = np.linspace(drop_end, v_b, PLATEAU_SAMPLES)[1:]
    p_plateau = p_top - (v_plateau - drop_end) / (v_b - drop_end) * (p_top - p_end)
    before = curve.v_ml <= peak.v_ml
    after = curve.v_ml > v_b
    v = np.concatenate([curve.v_ml[before], v_drop, v_plateau, curve.v_ml[after]])
    p = np.concatenate([curve.p_kpa[before], p_drop, p_plateau, curve.p_kpa[after]])
    length = np.concatenate([curve.l_mm[before], l_drop, mixture_mm(v_plateau), curve.l_mm[after]])
    return SegmentCurve(
        curve.name,
        v,
        p,
        length,
        V0_ml=curve.V0_ml,
        source=(
            f"{curve.source}; bulging after the peak: plateau {p_top:.2f} kPa "
            f"({depth_gain:g} x Maxwell's depth) from {drop_end:.3f} to {v_b:.3f} mL, "
            f"drop over {drop_width_ml:g} mL"
        ),
    )
