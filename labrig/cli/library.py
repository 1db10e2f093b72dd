"""``labrig library``: measured segments from single-segment runs, by name."""

from __future__ import annotations

from pathlib import Path

import click

LIBRARY_OPTION = click.option(
    "--library",
    "directory",
    type=click.Path(file_okay=False, path_type=Path),
    help="Folder of measured segments (default $LABRIG_LIBRARY or ./library).",
)


@click.group()
def library() -> None:
    """Build a library of measured segments (usable anywhere a SEG is accepted)."""


@library.command()
@click.argument("run", type=click.Path(dir_okay=False, path_type=Path))
@click.option("--name", required=True, help="The segment's name, e.g. S46-20-a.")
@LIBRARY_OPTION
@click.option("--replace", is_flag=True, help="Replace a segment of the same name.")
def add(run: Path, name: str, directory: Path | None, replace: bool) -> None:
    """Turn the single-segment run RUN into measured segment NAME: the mean inflation
    curve of its averaged repetitions, fitted to the segment's shape, as CSV with its
    provenance."""
    from labrig.analysis.measured_library import add_from_run

    segment = add_from_run(run, name, directory, replace=replace)
    curve = segment.provenance["curve"]
    peak = curve["peak"]
    click.echo(
        f"{segment.csv_path}: measured segment {name!r} from {run} (repetitions "
        f"{segment.provenance['repetitions_averaged']}, {curve['samples']} samples, peak "
        + (f"{peak['p_kpa']:.2f} kPa at {peak['v_ml']:.2f} mL" if peak else "none")
        + f"); provenance in {segment.provenance_path}"
    )


@library.command("list")
@LIBRARY_OPTION
def list_command(directory: Path | None) -> None:
    """List the measured segments in the library."""
    from labrig.analysis.measured_library import list_measured, resolve_library_dir

    segments = list_measured(directory)
    folder = resolve_library_dir(directory)
    if not segments:
        click.echo(f"{folder}: no measured segments (labrig library add RUN.h5 --name NAME)")
        return
    for segment in segments:
        run = segment.provenance.get("run", {})
        click.echo(f"{segment.name}\t{run.get('title', '?')}\t{run.get('path', '?')}")
