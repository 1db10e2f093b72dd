"""The 13 paper-numbers segments without a pressure peak: the single-segment numbers of
decision record 0013.

Run: python tests/benchmarks/no_peak.py

For each of the 36 ``paper:`` segments (record 0008's form, nothing changed) it prints the
tube's length at rest under the braids' force F (S35, uniaxial tension) and the shortest
any clamp of the tube's ends at its radius can make it (the whole wall held at its
radius, plane strain: F/(2 pi R H mu) = lambda - lambda^-3), the braid angle at rest, the
length the free tube under F reaches at its own pressure peak (S38's maximum, contact
ignored), the length at which it meets the strips, and whether the segment peaks.

Then, for the 13 without a peak and B42-T24 (the closest that peaks), the tube with its
ends held at their radius by the couplings (``clamped_tube``): its rest length, its
highest pressure before it meets the strips (the tube's outer volume reaching the
elastica envelope's at its length, or the strips straight) and whether that is a peak.

Last, the common length c by which each end of the tube would have to be held inside its
coupling (free tube L_tube - 2c) for the braids to bow at rest and for the segment to
peak, and the statements judged on single curves (``segment_statements.shape_outcomes``)
with no clamp, the smallest c for which all 36 peak and FURTHER_CLAMP_MM: what such a
clamp would do if a measurement gave it, not a library.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
from scipy.optimize import brentq

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from labrig.model.segments import elastica
from labrig.model.segments.braided import interior_maximum
from labrig.model.segments.catalog import library_names, library_segment
from labrig.model.segments.clamped_tube import ClampedTube
from labrig.model.segments.paper_braided import PaperBraidedSegment
from labrig.paper.segment_statements import shape_outcomes

# the free tube's peak lies below this axial stretch for every F of S32
_STRETCH_BOUND = 3.0
# the clamp lengths tried (mm per end) and the resolution of the smallest that works
_CLAMP_MM = 6.0
_CLAMP_XTOL_MM = 0.01
# the clamp whose single-segment statements are printed beside none and the smallest for
# which all 36 peak (found below), to show how the verdicts move with it
FURTHER_CLAMP_MM = 5.0
# the clamped tube's middle hoop stretches: from below rest (p < 0) past every peak
_MID_HOOPS = np.arange(0.74, 2.2, 0.02)


def plane_strain_stretch(segment) -> float:
    """lambda of the wall held at its radius under F: F/(2 pi R H mu) = lambda - lambda^-3."""
    f = segment.axial_force_n / (
        2 * np.pi * segment.radius_mm * segment.thickness_mm * segment.shear_modulus_mpa
    )
    return brentq(lambda lam: lam - lam**-3 - f, 1.0, 10.0, xtol=1e-14)


def free_peak_stretch(segment) -> float:
    """lambda_z at the free tube's own pressure peak under F, the strips ignored."""
    return interior_maximum(lambda lz: segment.tube_state(lz)[1], segment.lambda_z0, _STRETCH_BOUND)


def peaks_with_clamp(segment, clamp_mm: float) -> bool:
    shorter = PaperBraidedSegment(segment.l_braid_mm, segment.l_tube_mm - 2 * clamp_mm)
    return shorter.peak_stretch is not None


def bows_with_clamp(segment, clamp_mm: float) -> bool:
    return segment.lambda_z0 * (segment.l_tube_mm - 2 * clamp_mm) < segment.l_braid_mm


def smallest_clamp_mm(segment, works) -> float:
    """The smallest clamp per end (mm, to _CLAMP_XTOL_MM, from above) from which ``works``
    holds (0 if it already does): bisection, the upper end kept."""
    low, high = 0.0, _CLAMP_MM
    if works(segment, low):
        return low
    while high - low > _CLAMP_XTOL_MM:
        middle = 0.5 * (low + high)
        low, high = (low, middle) if works(segment, middle) else (middle, high)
    return high


def clamped_row(segment) -> str:
    """The clamped tube's rest length, its highest pressure before it meets the strips and
    whether that is a peak (a maximum with a lower state after it, before contact)."""
    states = ClampedTube(segment).branch(_MID_HOOPS)
    p = np.array([s.p_kpa for s in states])
    length = np.array([s.l_mm for s in states])
    rest = int(np.flatnonzero(p >= 0)[0])
    share = -p[rest - 1] / (p[rest] - p[rest - 1])
    l_rest = length[rest - 1] + share * (length[rest] - length[rest - 1])
    braid = segment.l_braid_mm
    inside = np.array(
        [
            s.l_mm < braid
            and s.volume_mm3 + segment.wall_volume_mm3
            < float(elastica.envelope_volume_mm3(s.l_mm, braid, segment.end_radius_mm))
            for s in states
        ]
    )
    touch = next((k for k in range(rest, len(p)) if not inside[k]), len(p))
    top = rest + int(np.argmax(p[rest:touch])) if touch > rest else rest
    peaks = rest < top < touch - 1
    verdict = "a peak" if peaks else "no peak"
    rest_text = f"rest {l_rest:5.1f} mm (uniform {segment.lambda_z0 * segment.l_tube_mm:5.1f})"
    if l_rest >= braid:
        return f"{rest_text}: straight, no peak"
    return (
        f"{rest_text},"
        f" highest before the strips {p[top]:5.1f} kPa at {length[top]:5.1f} mm,"
        f" meets them at {length[min(touch, len(p) - 1)]:5.1f} mm: {verdict}"
    )


def main() -> None:
    print(
        "segment   F N   l0 mm  l0 plane mm  theta0 deg  l_peak mm  l_contact mm  peak"
        "  clamp to bow mm  clamp to peak mm"
    )
    bow, peak = [], []
    for name in library_names("paper"):
        seg = library_segment(name)
        l0 = seg.lambda_z0 * seg.l_tube_mm
        plane = plane_strain_stretch(seg) * seg.l_tube_mm
        theta0 = np.degrees(np.arccos(min(l0 / seg.l_braid_mm, 1.0)))
        l_peak = free_peak_stretch(seg) * seg.l_tube_mm
        l_contact = seg.free_end_stretch * seg.l_tube_mm
        bow.append(smallest_clamp_mm(seg, bows_with_clamp))
        peak.append(smallest_clamp_mm(seg, peaks_with_clamp))
        print(
            f"{name.split(':')[1]:8s} {seg.axial_force_n:5.2f} {l0:6.1f} {plane:11.1f}"
            f" {theta0:11.1f} {l_peak:10.1f} {l_contact:13.1f}"
            f"  {'yes' if seg.peak_stretch is not None else 'no ':3s}"
            f" {bow[-1]:16.2f} {peak[-1]:17.2f}"
        )
    print("\nthe tube with its ends held at their radius by the couplings:")
    for name in library_names("paper"):
        seg = library_segment(name)
        if seg.peak_stretch is None or name.endswith("B42-T24"):
            print(f"{name.split(':')[1]:8s} {clamped_row(seg)}", flush=True)
    print(f"\na clamp per end for every segment to bow at rest: {max(bow):.2f} mm")
    print(f"a clamp per end for every segment to peak: {max(peak):.2f} mm")
    for clamp in (0.0, max(peak), FURTHER_CLAMP_MM):
        print(f"\nthe single-segment statements with {clamp:.2f} mm of tube held in each coupling:")
        for outcome in shape_outcomes(_clamped_library(clamp), ""):
            print(f"  {outcome.key}: {outcome.labrig}: {'holds' if outcome.holds else 'no'}")


def _clamped_library(clamp_mm: float):
    """Name -> curve of the ``paper:`` form with the free tube L_tube - 2 clamp_mm."""

    def curve(name: str):
        braid, tube = (float(x) for x in name.lstrip("B").split("-T"))
        return PaperBraidedSegment(braid, tube - 2 * clamp_mm).curve(name)

    return curve


if __name__ == "__main__":
    main()
