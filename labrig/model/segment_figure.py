"""One segment's p(v) and l(v) side by side, as the paper's Fig. 1C/D draws them, with
the peak and valley marked and, for an analytical library segment, the volume at which
the braids touch the tube (``braid_contact_ml``: the curve stiffens after it). Drawn for
``labrig model curve --plot`` and the Python API's ``Segment.plot``.

matplotlib is imported inside the functions (Agg backend for files): the model itself
never needs it.
"""

from __future__ import annotations

from pathlib import Path

from labrig.model.segments.catalog import is_library_name, library_segment
from labrig.model.segments.curve import SegmentCurve

RAW_POINTS_PLOTTED = 20_000  # more rows than this are thinned evenly in the plot


def braid_contact_ml(spec: str) -> float | None:
    """Volume (mL) at which the braids touch the tube, for the analytical library
    segment named ``spec``; None for anything else (a Gent membrane, a measured
    table), which has no such contact."""
    if not is_library_name(spec):
        return None
    return library_segment(spec).contact_ml


def plot_curve(curve: SegmentCurve, contact_ml: float | None, png: Path) -> None:
    """The two panels written to ``png``, titled with the segment's name."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 2, figsize=(10, 4), constrained_layout=True)
    draw_curve(list(axes), curve, contact_ml)
    fig.suptitle(curve.name)
    fig.savefig(png, dpi=120)
    plt.close(fig)


def draw_curve(axes: list, curve: SegmentCurve, contact_ml: float | None) -> None:
    """The figure's two panels on ``axes``: p-v (kPa against mL) and l-v (mm against
    mL); a measured table's raw rows in grey under the curve used."""
    ax_p, ax_l = axes
    if curve.measured is not None:
        raw = curve.measured.raw[:: max(1, len(curve.measured.raw) // RAW_POINTS_PLOTTED)]
        ax_p.plot(raw[:, 0], raw[:, 1], ".", color="grey", markersize=2, label="raw rows")
        ax_l.plot(raw[:, 0], raw[:, 2], ".", color="grey", markersize=2)
    used = "" if curve.measured is None else f"curve used ({curve.measured.route})"
    ax_p.plot(curve.v_ml, curve.p_kpa, color="tab:blue", label=used or None)
    ax_l.plot(curve.v_ml, curve.l_mm, color="tab:green")
    marks = [(curve.peak, "v", "peak"), (curve.valley, "o", "valley")]
    for extremum, marker, label in marks:
        if extremum is None:
            continue
        ax_p.plot(extremum.v_ml, extremum.p_kpa, marker, color="tab:red", label=label)
        ax_l.plot(extremum.v_ml, curve.length_mm(extremum.v_ml), marker, color="tab:red")
    if contact_ml is not None:
        for ax in (ax_p, ax_l):
            ax.axvline(contact_ml, color="grey", linestyle="--", linewidth=0.8)
        ax_p.plot([], [], "--", color="grey", linewidth=0.8, label="contact")
    highest = max([e.p_kpa for e, _, _ in marks if e is not None], default=0.0)
    ax_p.set_ylim(0, min(curve.p_kpa[-1], max(100.0, 1.5 * highest)))
    ax_p.set_xlabel("supplied volume v (mL)")
    ax_p.set_ylabel("pressure p (kPa)")
    ax_l.set_xlabel("supplied volume v (mL)")
    ax_l.set_ylabel("length l (mm)")
    ax_p.legend(loc="lower right")
    for ax in (ax_p, ax_l):
        ax.set_xlim(0, curve.v_max_ml)
        ax.grid(alpha=0.3)
