"""``labrig model curve SEG``: one segment's p(v) and l(v), as a summary, JSON or a plot.

SEG is a library name (``B46-T20``), a Gent membrane (``gent-a``) or a measured-curve
CSV. The JSON (``labrig.model.curve_document``) carries the segment's table itself, so
the peak and valley it reports are samples of the arrays. For a measured table it also
says what was done to it (used as tabulated or fitted), the table's resolution (spacing,
step, noise) and whether a peak was kept; the plot then overlays the raw rows on the
curve used.
"""

from __future__ import annotations

import json
from pathlib import Path

import click

from labrig.cli.options import plot_option


def summary_lines(curve, contact_ml: float | None) -> list[str]:
    def point(extremum, none_text):
        if extremum is None:
            return none_text
        return f"{extremum.p_kpa:.2f} kPa at {extremum.v_ml:.3f} mL"

    lines = [
        f"{curve.name}: {curve.source}",
        f"  V0       {curve.V0_ml:.3f} mL enclosed at p = 0",
        f"  peak     {point(curve.peak, 'none: p(v) only rises')}",
        f"  valley   {point(curve.valley, 'none')}",
    ]
    if contact_ml is not None:
        lines.append(f"  contact  {contact_ml:.3f} mL (braids touch the tube; stiffening after)")
    lines.append(
        f"  table    {len(curve.v_ml)} samples, v 0 to {curve.v_max_ml:.3f} mL, "
        f"p up to {curve.p_kpa[-1]:.0f} kPa"
    )
    measured = curve.measured
    if measured is not None:
        what = "used as tabulated" if measured.route == "tabulated" else "fitted (robust)"
        lines.append(f"  import   {what}")
        lines.append(f"  rows     {measured.resolution.describe()}")
        resolves = (
            f"dips above {measured.min_dip_kpa:.3g} kPa count"
            if measured.min_dip_kpa > 0
            else "an undithered staircase: any dip it shows counts"
        )
        kept = (
            f"1 peak kept (dip {measured.dip_kpa:.3g} kPa; {resolves})"
            if measured.peak_kept
            else f"no peak kept ({resolves})"
        )
        lines.append(f"  peaks    {kept}")
    return lines


@click.command("curve")
@click.argument("seg")
@click.option("--json", "as_json", is_flag=True, help="Print the curve as one JSON object.")
@plot_option("Write p-v and l-v to this PNG.")
def curve(seg: str, as_json: bool, plot_png: Path | None) -> None:
    """Show the pressure-volume and length-volume curve of one segment SEG: a library
    name (B46-T20), gent-a/b/c, or a CSV with volume_ml,pressure_kpa,length_mm."""
    from labrig.model.segment_figure import braid_contact_ml, plot_curve
    from labrig.model.segments.catalog import load_segment

    segment = load_segment(seg)
    contact_ml = braid_contact_ml(seg)
    if plot_png is not None:
        plot_curve(segment, contact_ml, plot_png)
    if as_json:
        from labrig.model.curve_document import curve_document

        click.echo(json.dumps(curve_document(segment)))
        return
    for line in summary_lines(segment, contact_ml):
        click.echo(line)
    if plot_png is not None:
        click.echo(f"  plot     {plot_png}")
