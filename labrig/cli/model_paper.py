"""``labrig model paper`` and ``labrig model calibrate``: the model against the paper.

``paper`` prints every checkable statement of the paper (the constants it gives, Fig. 1C
and D, Fig. S4's trends, Movies S3-S6, Fig. 3, Fig. 4) beside what a library gives:
the paper's value, labrig's, the two-sided tolerance, whether it holds, its role (input,
fitted, selected on, prediction) and, where it does not hold, what the model does instead.
``--library`` picks the library (``paper``, ``paper-r``, ``calibrated``, ``si``; the
default library's otherwise), ``--si`` is ``--library si``. ``calibrate`` repeats the fit that
produced the calibrated library (``labrig.paper.fit``) and prints the fitted
constants and the objective; it changes nothing on disk.
"""

from __future__ import annotations

import json
from pathlib import Path

import click

from labrig.cli.options import plot_option

_LIBRARY_HELP = (
    "paper (the paper's numbers, tubing read as diameters), paper-r (the same with the braid "
    "tubing's radius as printed), paper-gent (the paper's numbers with Gent's latex past the "
    "peak, J_m = 97.2 from Gent 1996), paper-clamped (the paper's numbers with the tube held "
    "at its radius by the couplings), calibrated or si (the SI as printed)"
)


def _table(outcomes, title: str) -> None:
    from rich import box
    from rich.console import Console
    from rich.table import Table

    table = Table(title=title, box=box.SIMPLE_HEAD, pad_edge=False)
    for heading in ("statement", "paper", "labrig", "tolerance", "holds", "role", "why not"):
        table.add_column(heading, overflow="fold")
    for o in outcomes:
        table.add_row(
            o.statement,
            o.paper,
            o.labrig,
            o.tolerance,
            "yes" if o.holds else "NO",
            o.role,
            o.why,
        )
    Console().print(table)


def _evaluated(name: str, evaluate):
    """``evaluate(name)`` with the step it is at on a spinner on stderr (seconds to a
    minute and a half); on a stderr that is not a terminal, nothing is shown."""
    from rich.console import Console

    with Console(stderr=True).status(f"checking the {name} library against the paper") as shown:
        return evaluate(name, progress=lambda step: shown.update(f"the {name} library: {step}"))


def _fitted(library: str) -> dict | None:
    """The library's fitted constants, None where it fits none."""
    from labrig.model.segments.calibrated import CALIBRATION

    return CALIBRATION.as_dict() if library == "calibrated" else None


@click.command("paper")
@click.option("--json", "as_json", is_flag=True, help="Print the table as one JSON object.")
@click.option(
    "--library",
    "library",
    type=click.Choice(
        ["paper", "paper-r", "paper-gent", "paper-clamped", "calibrated", "si"],
        case_sensitive=False,
    ),
    default=None,
    help=f"The segment library to check: {_LIBRARY_HELP}. Default: the default library's.",
)
@click.option("--si", is_flag=True, help="Check the SI's segments as printed (--library si).")
@plot_option("Also draw the 36 segments' p-v and l-v beside the paper's peak range (Fig. 1C, D).")
def paper(as_json: bool, library: str | None, si: bool, plot_png: Path | None) -> None:
    """The paper's statements about its segments and actuators, and whether a segment
    library reproduces each (inputs, fitted ones and predictions)."""
    from labrig.model.segments.catalog import DEFAULT_LIBRARY, analytical_segment, library_names
    from labrig.paper.checker import evaluate
    from labrig.paper.statements import PEAK_RANGE_KPA

    if si and library not in (None, "si"):
        raise click.UsageError("--si is --library si: give one of them")
    name = "si" if si else (library or DEFAULT_LIBRARY).lower()
    outcomes = _evaluated(name, evaluate)
    holding = int(sum(bool(o.holds) for o in outcomes))
    fitted = _fitted(name)
    if plot_png is not None:
        from labrig.model.plots import plot_library

        peaks = next(o for o in outcomes if o.key == "peaks-range")
        plot_library(
            [analytical_segment(n) for n in library_names(name)],
            plot_png,
            peak_range_kpa=PEAK_RANGE_KPA,
            title=f"the {name} library: peaks {peaks.labrig}; the paper: {peaks.paper}",
        )
        if not as_json:
            click.echo(f"{plot_png}: the 36 segments beside the paper's peak range")
    if as_json:
        document = {
            "library": name,
            "default_library": DEFAULT_LIBRARY,
            "calibration": fitted,
            "fitted_constants": len(fitted or {}),
            "holding": holding,
            "statements": [o.as_dict() for o in outcomes],
        }
        click.echo(json.dumps(document))
        return
    _table(
        outcomes,
        f"the {name} library ({len(fitted or {})} fitted constants) against the paper: "
        f"{holding} of {len(outcomes)} hold",
    )


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
    from labrig.paper.fit import fit

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
