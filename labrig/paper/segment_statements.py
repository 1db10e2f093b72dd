"""The paper's statements about its single segments: the constants it gives (inputs),
the peak range and its trends (Fig. 1C, Fig. S4E and F, main text), and the length's
rise and fall (Fig. 1D)."""

from __future__ import annotations

import numpy as np

from labrig.paper.statements import (
    BRAIDS_MM,
    INPUT,
    MIN_SPREAD_KPA,
    PEAK_RANGE_KPA,
    PREDICTION,
    TUBES_MM,
    Library,
    Outcome,
    peak_pressures,
)

MU_PAPER_MPA = 0.49
# Fig. S4E: "for shorter braids, the peak in pressure is lower": at every L_tube the peak
# does not fall with L_braid and rises by at least this much from 40 to 50 mm
MIN_BRAID_RISE_KPA = 1.0
# Fig. S4F: "the pressure peak ... remain[s] unaltered" with L_tube: at every L_braid its
# range over L_tube is at most this share of the range of the per-L_braid means
MAX_TUBE_SHARE = 0.5
# Fig. 1D: "initially the segments elongate, but then shorten": both by at least 1 %,
# judged up to the sensor's full scale (the MPX5100's 100 kPa), where the paper measured
MIN_LENGTH_CHANGE = 0.01
SENSOR_FULL_SCALE_KPA = 100.0
# Fig. S4E: "L_braid strongly affects the volume at which stiffening occurs": the volume
# at which a segment first reaches the sensor's 100 kPa (above every peak, on the final
# steep rise) grows with L_braid at every L_tube by at least the volume tolerance
MIN_STIFFENING_RISE_ML = 3.0
# Fig. S4F: "shorter tubes lower the pressure of the softening region": the lowest
# pressure past the peak rises with L_tube at every L_braid by at least this much
MIN_SOFTENING_RISE_KPA = 1.0
# S31: "for the fluidic segment considered in this study theta < 40 degrees"
MAX_THETA_DEG = 40.0


def _name(prefix: str, braid: int, tube: int) -> str:
    return f"{prefix}B{braid}-T{tube}"


def _input_outcomes(library: Library, prefix: str) -> list[Outcome]:
    """The paper's mu and braid force, as each library's segments use them."""
    from labrig.model.segments.braided import braid_force_n
    from labrig.model.segments.catalog import library_segment

    segments = [library_segment(_name(prefix, b, t)) for b in BRAIDS_MM for t in TUBES_MM]
    moduli = sorted({round(s.shear_modulus_mpa, 4) for s in segments})
    ratios = sorted({round(s.axial_force_n / braid_force_n(s.l_braid_mm), 4) for s in segments})
    mu_text = f"{moduli[0]:g}" if len(moduli) == 1 else f"{moduli[0]:g}-{moduli[-1]:g}"
    force_text = "as S32" if ratios == [1.0] else f"{ratios[0]:g} x S32"
    mu_holds = moduli == [MU_PAPER_MPA]
    return [
        Outcome(
            "input-mu",
            "the latex's initial shear modulus mu = 0.49 MPa (SI, below S14)",
            "0.49 MPa",
            f"{mu_text} MPa",
            mu_holds,
            INPUT,
            "" if mu_holds else "the library uses another modulus",
            "exactly",
        ),
        Outcome(
            "input-force",
            "the braids' force F = 2nK/L_braid = 20.4 - 0.281 L_braid N (SI, S31-S32)",
            "20.4 - 0.281 L_braid N",
            force_text,
            ratios == [1.0],
            INPUT,
            "" if ratios == [1.0] else "the library scales the braids' force",
            "exactly",
        ),
    ]


def _peak_outcomes(peaks: dict[str, float | None]) -> list[Outcome]:
    values = [p for p in peaks.values() if p is not None]
    missing = [name.split(":")[-1] for name, p in peaks.items() if p is None]
    low, high = (min(values), max(values)) if values else (float("nan"),) * 2
    within = not missing and PEAK_RANGE_KPA[0] <= low and high <= PEAK_RANGE_KPA[1]
    spread = high - low if values else 0.0
    range_why = ""
    if missing:
        range_why = f"no peak (contact first): {', '.join(missing)}"
    elif not within:
        range_why = "peaks outside 65-85 kPa"
    return [
        Outcome(
            "peaks-range",
            "the 36 segments peak between 65 and 85 kPa (Fig. 1C)",
            "65-85 kPa",
            f"{low:.1f}-{high:.1f} kPa ({len(values)} of 36 with a peak)",
            within,
            PREDICTION,
            range_why,
            "every one of the 36 within 65-85 kPa",
        ),
        Outcome(
            "peaks-spread",
            "the peaks spread over the range (Fig. 1C): at least 10 kPa",
            ">= 10 kPa",
            f"{spread:.1f} kPa",
            spread >= MIN_SPREAD_KPA,
            PREDICTION,
            "" if spread >= MIN_SPREAD_KPA else "the peak barely depends on the geometry",
            ">= 10 kPa",
        ),
    ]


def _grid(peaks: dict[str, float | None], prefix: str) -> np.ndarray:
    """Peaks as an L_braid x L_tube array (NaN without a peak)."""
    return np.array(
        [
            [np.nan if (p := peaks[_name(prefix, b, t)]) is None else p for t in TUBES_MM]
            for b in BRAIDS_MM
        ]
    )


def _trend_outcomes(peaks: dict[str, float | None], prefix: str) -> list[Outcome]:
    grid = _grid(peaks, prefix)
    rises, braid_text = [], []
    for j, tube in enumerate(TUBES_MM):
        column = grid[:, j][~np.isnan(grid[:, j])]
        ok = len(column) >= 2 and np.all(np.diff(column) >= 0)
        ok = ok and column[-1] - column[0] >= MIN_BRAID_RISE_KPA
        rises.append(bool(ok))
        rise = f"{column[-1] - column[0]:+.1f}" if len(column) >= 2 else "n/a"
        braid_text.append(f"T{tube}: {rise}")
    tube_ranges = [np.ptp(row[~np.isnan(row)]) for row in grid if np.sum(~np.isnan(row)) >= 2]
    means = [np.nanmean(row) for row in grid if np.any(~np.isnan(row))]
    braid_range = float(np.ptp(means)) if len(means) >= 2 else 0.0
    worst_tube = max(tube_ranges, default=float("nan"))
    independent = bool(tube_ranges) and worst_tube <= MAX_TUBE_SHARE * braid_range
    return [
        Outcome(
            "peaks-rise-with-braid",
            "shorter braids lower the peak (main text, Fig. S4E)",
            "the peak rises with L_braid at every L_tube",
            "rise 40->50 mm: " + ", ".join(braid_text) + " kPa",
            all(rises),
            PREDICTION,
            "" if all(rises) else "at some L_tube the peak does not rise with L_braid",
            "non-decreasing and >= 1 kPa from 40 to 50 mm, at every L_tube",
        ),
        Outcome(
            "peaks-independent-of-tube",
            "with L_braid fixed, the pressure peak does not change with L_tube (Fig. S4F)",
            "unaltered",
            f"largest range over L_tube {worst_tube:.1f} kPa; over L_braid {braid_range:.1f} kPa",
            independent,
            PREDICTION,
            "" if independent else "L_tube moves the peak as much as L_braid does",
            "range over L_tube <= half the range over L_braid",
        ),
    ]


def _below_full_scale(curve):
    """The curve's volumes, pressures and lengths up to where it first passes the
    sensor's full scale."""
    over = np.flatnonzero(np.asarray(curve.p_kpa) > SENSOR_FULL_SCALE_KPA)
    end = int(over[0]) + 1 if len(over) else len(curve.p_kpa)
    return np.asarray(curve.v_ml)[:end], np.asarray(curve.p_kpa)[:end], curve.l_mm[:end]


def _length_outcome(library: Library, prefix: str) -> Outcome:
    failing = []
    for braid in BRAIDS_MM:
        for tube in TUBES_MM:
            _, _, length = _below_full_scale(library(_name(prefix, braid, tube)))
            top = int(np.argmax(length))
            grows = length[top] >= (1 + MIN_LENGTH_CHANGE) * length[0]
            shrinks = length[-1] <= (1 - MIN_LENGTH_CHANGE) * length[top]
            if not (grows and shrinks):
                failing.append(f"B{braid}-T{tube}")
    holds = not failing
    return Outcome(
        "fig1d-length",
        "every segment first lengthens, then shortens once the braids touch (Fig. 1D), "
        "up to the sensor's 100 kPa",
        "lengthens, then shortens",
        f"{36 - len(failing)} of 36 do",
        holds,
        PREDICTION,
        "" if holds else f"not: {', '.join(failing)}",
        "each by at least 1 %, every segment, judged up to 100 kPa",
    )


def stiffening_volume_ml(curve) -> float | None:
    """The volume at which the segment first reaches the sensor's full scale (None if
    its curve never does)."""
    v, p = np.asarray(curve.v_ml), np.asarray(curve.p_kpa)
    over = np.flatnonzero(p >= SENSOR_FULL_SCALE_KPA)
    if not len(over):
        return None
    k = int(over[0])
    if k == 0:
        return float(v[0])
    return float(np.interp(SENSOR_FULL_SCALE_KPA, p[k - 1 : k + 1], v[k - 1 : k + 1]))


def softening_pressure_kpa(curve) -> float | None:
    """The lowest pressure past the peak and below the sensor's full scale (None
    without a peak)."""
    peak = curve.peak
    if peak is None:
        return None
    v, p, _ = _below_full_scale(curve)
    after = p[v >= peak.v_ml]
    return float(after.min()) if len(after) else None


def _table(library: Library, prefix: str, of) -> np.ndarray:
    """``of(curve)`` as an L_braid x L_tube array (NaN where it is None)."""
    return np.array(
        [
            [np.nan if (x := of(library(_name(prefix, b, t)))) is None else x for t in TUBES_MM]
            for b in BRAIDS_MM
        ]
    )


def _stiffening_outcomes(library: Library, prefix: str) -> list[Outcome]:
    grid = _table(library, prefix, stiffening_volume_ml)
    rises, text = [], []
    for j, tube in enumerate(TUBES_MM):
        column = grid[:, j]
        ok = not np.any(np.isnan(column)) and bool(np.all(np.diff(column) >= 0))
        ok = ok and column[-1] - column[0] >= MIN_STIFFENING_RISE_ML
        rises.append(ok)
        text.append(f"T{tube}: {column[0]:.1f}->{column[-1]:.1f}")
    complete = [row for row in grid if not np.any(np.isnan(row))]
    tube_range = max((float(np.ptp(row)) for row in complete), default=float("nan"))
    braid_range = float(np.ptp([np.mean(row) for row in complete])) if len(complete) >= 2 else 0.0
    independent = len(complete) == len(BRAIDS_MM) and tube_range <= MAX_TUBE_SHARE * braid_range
    return [
        Outcome(
            "stiffening-rise-with-braid",
            "the volume at which stiffening occurs rises with L_braid (Fig. S4E)",
            "rises with L_braid",
            "100 kPa at (40->50 mm) " + ", ".join(text) + " mL",
            all(rises),
            PREDICTION,
            ""
            if all(rises)
            else "at some L_tube it does not rise by 3 mL, or 100 kPa is never met",
            "the volume at 100 kPa non-decreasing and >= 3 mL from 40 to 50 mm, at every L_tube",
        ),
        Outcome(
            "stiffening-independent-of-tube",
            "with L_braid fixed, the volume at which stiffening occurs does not change with "
            "L_tube (Fig. S4F)",
            "unaltered",
            f"largest range over L_tube {tube_range:.1f} mL; over L_braid {braid_range:.1f} mL",
            independent,
            PREDICTION,
            "" if independent else "L_tube moves the stiffening as much as L_braid does",
            "range over L_tube <= half the range over L_braid",
        ),
    ]


def _softening_outcome(library: Library, prefix: str) -> Outcome:
    grid = _table(library, prefix, softening_pressure_kpa)
    rises, text = [], []
    for i, braid in enumerate(BRAIDS_MM):
        row = grid[i]
        ok = not np.any(np.isnan(row)) and bool(np.all(np.diff(row) >= 0))
        ok = ok and row[-1] - row[0] >= MIN_SOFTENING_RISE_KPA
        rises.append(ok)
        rise = "n/a" if np.isnan(row[0]) or np.isnan(row[-1]) else f"{row[-1] - row[0]:+.1f}"
        text.append(f"B{braid}: {rise}")
    holds = all(rises)
    return Outcome(
        "softening-lower-with-shorter-tube",
        "shorter tubes lower the pressure of the softening region (Fig. S4F)",
        "rises with L_tube",
        "lowest pressure past the peak, 20->30 mm: " + ", ".join(text) + " kPa",
        holds,
        PREDICTION,
        "" if holds else "at some L_braid it does not rise with L_tube (or no peak)",
        "non-decreasing and >= 1 kPa from 20 to 30 mm, at every L_braid, every segment a peak",
    )


def _theta_outcome(library: Library, prefix: str) -> Outcome:
    """The braids' angle at rest, where it is largest before contact (the tube only
    lengthens until the braids touch): cos theta = l / L_braid (S41)."""
    angles = {}
    for braid in BRAIDS_MM:
        for tube in TUBES_MM:
            length = float(library(_name(prefix, braid, tube)).l_mm[0])
            angles[f"B{braid}-T{tube}"] = float(np.degrees(np.arccos(min(length / braid, 1.0))))
    over = [name for name, angle in angles.items() if angle >= MAX_THETA_DEG]
    worst = max(angles, key=angles.get)
    return Outcome(
        "theta-below-40",
        "the braids' angle stays below 40 degrees (S31)",
        "theta < 40 deg",
        f"at rest {min(angles.values()):.1f}-{angles[worst]:.1f} deg ({worst})",
        not over,
        PREDICTION,
        "" if not over else f"{len(over)} of 36 at or above 40 deg",
        "every segment at rest",
    )


def evaluate(library: Library, prefix: str) -> list[Outcome]:
    return _input_outcomes(library, prefix) + shape_outcomes(library, prefix)


def shape_outcomes(library: Library, prefix: str) -> list[Outcome]:
    """The statements judged on the 36 curves alone (not the constants behind them): what
    a family of segments that is not a library can be measured by (docs/decisions/0013)."""
    peaks = peak_pressures(library, prefix)
    return (
        _peak_outcomes(peaks)
        + _trend_outcomes(peaks, prefix)
        + [_length_outcome(library, prefix)]
        + _stiffening_outcomes(library, prefix)
        + [_softening_outcome(library, prefix), _theta_outcome(library, prefix)]
    )
