"""The paper-numbers segments with the bulge held by the strips: the single-segment
numbers of decision record 0011, beside record 0008's.

Run: python tests/benchmarks/held_bulge.py [--as-printed] [--limiting-invariant J_M]

With ``--as-printed`` both forms take the braid tubing's inner radius as the paper prints
it, 7.94 mm (record 0009's reading, the ``paper-r:`` library), instead of 3.97 mm.
With ``--limiting-invariant J_M`` the two phases of 0011 are Gent's latex (record 0011's
Consequences: a bracket measured after its decision; the paper gives no J_m). A segment
whose path cannot be followed is reported as such.

For each of the 36 segments, record 0008's segment (``paper:``) and record 0011's
(``HeldBulgeSegment``: past the peak a two-phase tube at the strips' length) are built
from the paper's numbers, and for each the table prints: the peak (kPa, or "-" without
one), the lowest pressure past it below 100 kPa (the softening region), the secant from
60 to 75 kPa on the last rising branch (where a second segment of a pair crosses its
peak; record 0010), the volume at 100 kPa (the stiffening), whether the length first
grows and then shrinks by 1 % each up to 100 kPa (Fig. 1D), and for 0011 the fill (the
two-phase path's end) and its smallest contact pressure on the strips. Then the Fig. S3/S4
trends with the statements' own rules (``labrig.paper.segment_statements``). Single
segments only: no actuator is computed.
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

from benchmarks.giving_braids import band_slope

from labrig.model.segments.catalog import library_segment
from labrig.model.segments.held_bulge import HeldBulgeSegment
from labrig.model.segments.paper_braided import (
    BRAID_INNER_RADIUS_AS_PRINTED_MM,
    BRAID_INNER_RADIUS_MM,
)
from labrig.paper.segment_statements import (
    SENSOR_FULL_SCALE_KPA,
    softening_pressure_kpa,
    stiffening_volume_ml,
)

BRAIDS, TUBES = tuple(range(40, 51, 2)), tuple(range(20, 31, 2))
STEEP_KPA_PER_ML = 12.0  # the audit's slope for Movie S3's second crossing to snap


def lengthens_then_shortens(curve) -> bool:
    """Fig. 1D judged up to the sensor's full scale, 1 % each way (the statement's rule)."""
    p = np.asarray(curve.p_kpa)
    over = np.flatnonzero(p > SENSOR_FULL_SCALE_KPA)
    end = int(over[0]) + 1 if len(over) else len(p)
    length = np.asarray(curve.l_mm)[:end]
    top = int(np.argmax(length))
    return bool(length[top] >= 1.01 * length[0] and length[-1] <= 0.99 * length[top])


def measure(segment) -> dict:
    curve = segment.curve()
    v, p = np.asarray(curve.v_ml), np.asarray(curve.p_kpa)
    peak = curve.peak
    return {
        "peak": None if peak is None else peak.p_kpa,
        "soft": softening_pressure_kpa(curve),
        "slope": band_slope(v, p),
        "v100": stiffening_volume_ml(curve),
        "fig1d": lengthens_then_shortens(curve),
    }


def _f(x, digits=1) -> str:
    return "-" if x is None else f"{x:.{digits}f}"


def _cell(rows: dict, b: int, t: int, key: str) -> float:
    row = rows.get((b, t))
    return np.nan if row is None or row[key] is None else row[key]


def _trends(rows: dict, key: str) -> str:
    grid = np.array([[_cell(rows, b, t, key) for t in TUBES] for b in BRAIDS])
    rise_braid = all(
        np.all(np.diff(grid[:, j]) >= 0) and grid[-1, j] - grid[0, j] >= 3 for j in range(6)
    )
    complete = [row for row in grid if not np.any(np.isnan(row))]
    tube_range = max((float(np.ptp(row)) for row in complete), default=float("nan"))
    braid_range = float(np.ptp([np.mean(row) for row in complete])) if len(complete) >= 2 else 0.0
    return (
        f"rises >= 3 mL with L_braid at every L_tube: {rise_braid}; largest range over L_tube "
        f"{tube_range:.1f} mL, over L_braid {braid_range:.1f} mL"
    )


def _softening(rows: dict) -> str:
    ok, text = True, []
    for b in BRAIDS:
        row = [None if (b, t) not in rows else rows[b, t]["soft"] for t in TUBES]
        if any(x is None for x in row):
            ok = False
            text.append(f"B{b}: n/a")
            continue
        ok = ok and bool(np.all(np.diff(row) >= 0)) and row[-1] - row[0] >= 1.0
        text.append(f"B{b}: {row[0]:.1f}->{row[-1]:.1f}")
    return f"rises with L_tube at every L_braid: {ok} ({', '.join(text)} kPa)"


def main() -> None:
    as_printed = "--as-printed" in sys.argv[1:]
    arguments = sys.argv[1:]
    flag = "--limiting-invariant"
    limit = float(arguments[arguments.index(flag) + 1]) if flag in arguments else None
    library = "paper-r" if as_printed else "paper"
    radius = BRAID_INNER_RADIUS_AS_PRINTED_MM if as_printed else BRAID_INNER_RADIUS_MM
    latex = "neo-Hookean" if limit is None else f"Gent, J_m = {limit:g}"
    print(f"braid tubing's inner radius {radius:g} mm (0008: {library}:); 0011's phases {latex}")
    print(
        "segment | 0008: peak, soft, slope 60-75, v@100, 1D | "
        "0011: peak, soft, slope 60-75, v@100, 1D, fill mL/kPa, min contact kPa"
    )
    old, new = {}, {}
    started = time.process_time()
    for b in BRAIDS:
        for t in TUBES:
            paper = library_segment(f"{library}:B{b}-T{t}")
            held = HeldBulgeSegment(
                float(b), float(t), envelope_radius_mm=radius, limiting_invariant=limit
            )
            try:
                old[b, t], new[b, t] = measure(paper), measure(held)
            except ValueError as error:
                print(f"B{b}-T{t} | 0011: not computed: {error}")
                continue
            path = held.held_path
            fill = "-" if path is None else f"{path.v_ml[-1]:.2f}/{path.p_kpa[-1]:.0f}"
            contact = "-" if path is None else f"{path.contact_kpa.min():.1f}"
            cells = []
            for row in (old[b, t], new[b, t]):
                cells.append(
                    f"{_f(row['peak'])}, {_f(row['soft'])}, {_f(row['slope'])}, "
                    f"{_f(row['v100'], 2)}, {'yes' if row['fig1d'] else 'no'}"
                )
            print(f"B{b}-T{t} | {cells[0]} | {cells[1]}, {fill}, {contact}")
    cpu = time.process_time() - started
    for label, rows in (("0008", old), ("0011", new)):
        values = list(rows.values())
        peaks = [r["peak"] for r in values if r["peak"] is not None]
        slopes = [r["slope"] for r in values if r["peak"] is not None and r["slope"] is not None]
        gentle = sum(s <= STEEP_KPA_PER_ML for s in slopes)
        print(
            f"{label}: {len(peaks)} of 36 peak ({min(peaks):.1f}-{max(peaks):.1f} kPa); of those, "
            f"slope 60-75 kPa <= {STEEP_KPA_PER_ML:g} kPa/mL in {gentle} of {len(slopes)} "
            f"({min(slopes):.1f}-{max(slopes):.1f} kPa/mL, median {np.median(slopes):.1f}); "
            f"Fig. 1D to 100 kPa: {sum(r['fig1d'] for r in values)} of 36"
        )
        print(f"  stiffening (v at 100 kPa): {_trends(rows, 'v100')}")
        print(f"  softening region: {_softening(rows)}")
    print(f"both forms, all 36: {cpu:.1f} s CPU")


if __name__ == "__main__":
    main()
