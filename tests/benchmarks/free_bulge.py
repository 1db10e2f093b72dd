"""The paper-numbers segments with Gent's latex past the peak and a bulge free of the
strips where it does not press on them: the single-segment numbers of decision record
0012, beside record 0008's.

Run: python tests/benchmarks/free_bulge.py [J_M ...]   (default: 97.2 70 130, the record's
value and bracket)

For each J_m and each of the 36 segments, record 0012's segment (``GentBulgeSegment``) is
built from the paper's numbers and the table prints: the peak (kPa, "-" without one), the
lowest pressure past it below 100 kPa and the dip (peak less that), the secant from 60 to
75 kPa on the last rising branch, the volume at 100 kPa, Fig. 1D up to 100 kPa, the fill
(mL/kPa), the bulge's smallest contact pressure on the strips while held (kPa; 0 where it
is only free) and the free plateau's pressure (kPa, "-" where the bulge starts held). Then
the same summary and Fig. S3/S4 trends as ``held_bulge.py``. Single segments only: no
actuator is computed.
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

from benchmarks.held_bulge import BRAIDS, STEEP_KPA_PER_ML, TUBES, _f, _softening, _trends, measure

from labrig.model.segments.catalog import library_segment
from labrig.model.segments.free_bulge import (
    GENT_LIMITING_INVARIANT,
    LIMITING_INVARIANT_BRACKET,
    GentBulgeSegment,
)


def _held_contact(path) -> str:
    held = path.contact_kpa[path.contact_kpa != 0.0]
    return "0" if held.size == 0 else f"{held.min():.1f}"


def _plateau(path) -> str:
    free = path.contact_kpa == 0.0
    return "-" if not free[0] else f"{path.p_kpa[0]:.1f}"


def table(limit: float, old: dict) -> dict:
    print(f"\nGent's latex past the peak, J_m = {limit:g}")
    print(
        "segment | 0008: peak, soft, dip, slope | 0012: peak, soft, dip, slope, v@100, 1D, "
        "fill mL/kPa, min held contact kPa, free plateau kPa"
    )
    rows, started = {}, time.process_time()
    for b in BRAIDS:
        for t in TUBES:
            if (b, t) not in old:
                old[b, t] = measure(library_segment(f"paper:B{b}-T{t}"))
            segment = GentBulgeSegment(float(b), float(t), limiting_invariant=limit)
            try:
                rows[b, t] = row = measure(segment)
            except ValueError as error:
                print(f"B{b}-T{t} | 0012: not computed: {error}")
                continue
            cells = []
            for r in (old[b, t], row):
                dip = None if r["peak"] is None or r["soft"] is None else r["peak"] - r["soft"]
                cells.append(f"{_f(r['peak'])}, {_f(r['soft'])}, {_f(dip)}, {_f(r['slope'])}")
            path = segment.held_path
            extra = (
                "-, -, -"
                if path is None
                else (
                    f"{path.v_ml[-1]:.2f}/{path.p_kpa[-1]:.0f}, "
                    f"{_held_contact(path)}, {_plateau(path)}"
                )
            )
            print(
                f"B{b}-T{t} | {cells[0]} | {cells[1]}, {_f(row['v100'], 2)}, "
                f"{'yes' if row['fig1d'] else 'no'}, {extra}"
            )
    cpu = time.process_time() - started
    values = list(rows.values())
    peaks = [r["peak"] for r in values if r["peak"] is not None]
    slopes = [r["slope"] for r in values if r["peak"] is not None and r["slope"] is not None]
    dips = [
        r["peak"] - r["soft"] for r in values if r["peak"] is not None and r["soft"] is not None
    ]
    gentle = sum(s <= STEEP_KPA_PER_ML for s in slopes)
    print(
        f"0012 (J_m = {limit:g}): computed {len(values)} of 36; {len(peaks)} peak; "
        f"slope 60-75 kPa <= {STEEP_KPA_PER_ML:g} kPa/mL in {gentle} of {len(slopes)} "
        f"({min(slopes):.1f}-{max(slopes):.1f}, median {np.median(slopes):.1f} kPa/mL); "
        f"dips {min(dips):.1f}-{max(dips):.1f} kPa (median {np.median(dips):.1f}); "
        f"Fig. 1D to 100 kPa: {sum(r['fig1d'] for r in values)} of {len(values)}"
    )
    print(f"  stiffening (v at 100 kPa): {_trends(rows, 'v100')}")
    print(f"  softening region: {_softening(rows)}")
    print(f"  all 36: {cpu:.1f} s CPU")
    return rows


def main() -> None:
    limits = [float(x) for x in sys.argv[1:]] or [
        GENT_LIMITING_INVARIANT,
        *LIMITING_INVARIANT_BRACKET,
    ]
    old: dict = {}
    for limit in limits:
        table(limit, old)


if __name__ == "__main__":
    main()
