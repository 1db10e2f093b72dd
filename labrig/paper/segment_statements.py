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
# Fig. 1D: "initially the segments elongate, but then shorten": both by at least 1 %
MIN_LENGTH_CHANGE = 0.01


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


def _length_outcome(library: Library, prefix: str) -> Outcome:
    failing = []
    for braid in BRAIDS_MM:
        for tube in TUBES_MM:
            curve = library(_name(prefix, braid, tube))
            top = int(np.argmax(curve.l_mm))
            grows = curve.l_mm[top] >= (1 + MIN_LENGTH_CHANGE) * curve.l_mm[0]
            shrinks = curve.l_mm[-1] <= (1 - MIN_LENGTH_CHANGE) * curve.l_mm[top]
            if not (grows and shrinks):
                failing.append(f"B{braid}-T{tube}")
    holds = not failing
    return Outcome(
        "fig1d-length",
        "every segment first lengthens, then shortens once the braids touch (Fig. 1D)",
        "lengthens, then shortens",
        f"{36 - len(failing)} of 36 do",
        holds,
        PREDICTION,
        "" if holds else f"not: {', '.join(failing)}",
        "each by at least 1 %, every segment",
    )


def evaluate(library: Library, prefix: str) -> list[Outcome]:
    peaks = peak_pressures(library, prefix)
    return (
        _input_outcomes(library, prefix)
        + _peak_outcomes(peaks)
        + _trend_outcomes(peaks, prefix)
        + [_length_outcome(library, prefix)]
    )
