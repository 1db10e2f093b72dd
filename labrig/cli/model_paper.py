"""``labrig model paper`` and ``labrig model calibrate``: the model against the paper.

``paper`` prints the paper's nine statements (Fig. 1C, Movies S3-S6) beside what the
library gives, whether each holds and, where not, what the model does instead; ``--si``
makes the same table for the SI's uncalibrated segments. ``calibrate`` repeats the fit
that produced the calibrated library (``labrig.model.paper.fit``) and prints the fitted
constants and the objective; it changes nothing on disk.
"""

from __future__ import annotations

import json
from pathlib import Path

import click

from labrig.cli.options import plot_option


def _library(si: bool):
    from labrig.model.segments.catalog import SI_PREFIX, analytical_segment

    return analytical_segment, (SI_PREFIX if si else "")


def _table(outcomes, title: str) -> None:
    from rich import box
    from rich.console import Console
    from rich.table import Table

    table = Table(title=title, box=box.SIMPLE_HEAD, pad_edge=False)
    for heading in ("statement", "paper", "labrig", "holds", "role", "why not"):
        table.add_column(heading, overflow="fold")
    for o in outcomes:
        table.add_row(o.statement, o.paper, o.labrig, "yes" if o.holds else "NO", o.role, o.why)
    Console().print(table)


@click.command("paper")
@click.option("--json", "as_json", is_flag=True, help="Print the table as one JSON object.")
@click.option("--si", is_flag=True, help="Check the SI's uncalibrated segments (SI-B46-T20 ...).")
@plot_option("Also draw the 36 segments' p-v and l-v beside the paper's peak range (Fig. 1C, D).")
def paper(as_json: bool, si: bool, plot_png: Path | None) -> None:
    """The paper's statements about its segments and actuators, and whether the model's
    library reproduces each (fitted ones and predictions)."""
    from labrig.model.paper.statements import PEAK_RANGE_KPA, evaluate, library_names
    from labrig.model.segments.calibrated import CALIBRATION

    library, prefix = _library(si)
    outcomes = evaluate(library, prefix)
    holding = int(sum(bool(o.holds) for o in outcomes))
    name = "SI (uncalibrated)" if si else "calibrated"
    if plot_png is not None:
        from labrig.model.plots import plot_library

        peaks = next(o for o in outcomes if o.key == "peaks-range")
        plot_library(
            [library(n) for n in library_names(prefix)],
            plot_png,
            peak_range_kpa=PEAK_RANGE_KPA,
            title=f"the {name} library: peaks {peaks.labrig}; the paper: {peaks.paper}",
        )
        if not as_json:
            click.echo(f"{plot_png}: the 36 segments beside the paper's peak range")
    if as_json:
        document = {
            "library": name,
            "calibration": None if si else CALIBRATION.as_dict(),
            "holding": holding,
            "statements": [o.as_dict() for o in outcomes],
        }
        click.echo(json.dumps(document))
        return
    _table(outcomes, f"the {name} library against the paper: {holding} of {len(outcomes)} hold")


@click.command("calibrate")
@click.option(
    "--max-evaluations",
    type=click.IntRange(min=1),
    default=120,
    show_default=True,
    help="Objective evaluations of the simplex (about 5 s each).",
)
@click.option("--json", "as_json", is_flag=True, help="Print the result as one JSON object.")
def calibrate(max_evaluations: int, as_json: bool) -> None:
    """Fit the library's free constants to the paper's peak range and Movie S3
    (scipy.optimize, Nelder-Mead) from the current calibration; print the result."""
    from labrig.model.paper.fit import fit

    def progress(calibration, value):
        if not as_json:
            click.echo(f"  objective {value:10.4f}  {calibration.as_dict()}", err=True)

    found = fit(max_evaluations=max_evaluations, progress=progress)
    if as_json:
        click.echo(
            json.dumps(
                {
                    "calibration": found.calibration.as_dict(),
                    "objective": found.objective,
                    "start_objective": found.start_objective,
                    "evaluations": found.evaluations,
                }
            )
        )
        return
    click.echo(
        f"objective {found.start_objective:.4f} -> {found.objective:.4f} "
        f"in {found.evaluations} evaluations"
    )
    for key, value in found.calibration.as_dict().items():
        click.echo(f"  {key:20s} {value:.6g}")
