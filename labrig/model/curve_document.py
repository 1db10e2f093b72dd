"""One segment's curve as the JSON object scripts read from ``labrig model curve --json``
(``curve_document``), built here for that command and for the Python API's
``labrig.segment``, so the two cannot drift apart.

The object carries the segment's table itself (v_ml in mL, p_kpa in kPa, l_mm in mm), so
the peak and valley it reports are samples of those arrays; for a measured table it also
says what was done to it (``measured``).
"""

from __future__ import annotations

from labrig.model.segments.curve import Extremum, SegmentCurve
from labrig.vocabulary import ALIASES, beside_fields


def extremum_document(extremum: Extremum | None) -> dict[str, float] | None:
    """A peak or valley as ``{"v_ml", "p_kpa"}`` (mL, kPa); None for none."""
    return None if extremum is None else {"v_ml": extremum.v_ml, "p_kpa": extremum.p_kpa}


def measured_document(curve: SegmentCurve) -> dict:
    """What was done to a measured table: its route (used as tabulated or fitted), the
    rows' resolution (spacings in mL, step and noise in kPa), the prominence a dip
    needs to count (kPa) and whether a peak was kept (with its dip, kPa)."""
    measured = curve.measured
    res = measured.resolution
    return {
        "route": measured.route,
        "rows": res.rows,
        "spacing_ml": res.spacing_ml,
        "spacing_min_ml": res.spacing_min_ml,
        "spacing_max_ml": res.spacing_max_ml,
        "uniform": res.uniform,
        "step_kpa": res.step_kpa,
        "noise_kpa": res.noise_kpa,
        "prominence_kpa": measured.min_dip_kpa,
        "peaks_kept": int(measured.peak_kept),
        "dip_kpa": measured.dip_kpa,
    }


def curve_document(curve: SegmentCurve) -> dict:
    """``labrig model curve --json``'s object: name, V0_ml (mL enclosed at p = 0),
    peak and valley, the arrays v_ml, p_kpa, l_mm (each with its vocabulary name right
    after it: ``volume_ml``, ``pressure_kpa``, ``segments_length_mm``) and, for a
    measured table, ``measured``."""
    fields = {
        "name": curve.name,
        "V0_ml": curve.V0_ml,
        "peak": extremum_document(curve.peak),
        "valley": extremum_document(curve.valley),
        "v_ml": curve.v_ml.tolist(),
        "p_kpa": curve.p_kpa.tolist(),
        "l_mm": curve.l_mm.tolist(),
    }
    document = beside_fields(fields, ALIASES["model curve"])
    if curve.measured is not None:
        document["measured"] = measured_document(curve)
    return document
