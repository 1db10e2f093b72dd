"""``labrig show | plot | export | compare | recover FILE.h5``: reviewing run files.

The review commands read a run and its stored analysis (``/entry/analysis``, written by
the runner after each run); a file without one is analysed on the fly, in memory, and
nothing is written unless ``compare --store`` asks for it. ``recover`` is the one that
repairs: it clears the "open for writing" flag a killed run leaves, marks the unfinished
run and repetition as aborted, and stores the analysis of what was recorded.
"""

from __future__ import annotations

from pathlib import Path

import click

from labrig.errors import InputError


class RunFileArgument(click.Path):
    """A run file named on the command line, walked by a watched child process
    (``labrig.recording.file_check``) as soon as it is read, before the command loads
    its analysis (seconds of imports): a damaged file is answered at once."""

    def __init__(self) -> None:
        super().__init__(dir_okay=False, path_type=Path)

    def convert(self, value, param, ctx):
        path = super().convert(value, param, ctx)
        if path.is_file():  # a missing file, a pipe: the command's own reading says so
            from labrig.recording.file_check import check_file

            check_file(path)
        return path


FILE = RunFileArgument()


def _console():
    from rich.console import Console

    return Console(highlight=False)


def load(path: Path, *, compare_model: bool = True):
    """(record, analysis, stored): the run, its stored analysis or one computed now."""
    from labrig.analysis.analyse import analyse, settings_for
    from labrig.analysis.results import read_analysis
    from labrig.analysis.runfile import load_run
    from labrig.recording.run_reader import open_run

    record = load_run(path)
    with open_run(path) as run:
        stored = read_analysis(path, run)
    if stored is not None:
        return record, stored, True
    settings = settings_for(record)
    if not compare_model:
        from dataclasses import replace

        settings = replace(settings, compare_model=False)
    return record, analyse(path, record=record, settings=settings), False


def _warn_open(record) -> None:
    from labrig.recording.run_file_lock import held_by_a_process

    if not record.writer_flag_set:
        return
    if held_by_a_process(record.path):
        click.echo(
            f"note: {record.path} is being recorded by a labrig process; shown as of its "
            "last flush."
        )
    else:
        click.echo(
            f"warning: {record.path} is still flagged open, and no process writes it (its "
            f"run was killed); shown as of its last flush. `labrig recover {record.path}` "
            "closes it."
        )


def _computed_note(stored: bool) -> None:
    if not stored:
        click.echo(
            "note: this file has no stored analysis; computed now, not stored "
            "(`labrig compare FILE --store` stores it)"
        )


@click.command()
@click.argument("file", type=FILE)
def show(file: Path) -> None:
    """Show a run: metadata, protocol, each repetition's status and key figures, the
    transitions found and, if stored, the comparison with the model."""
    from labrig.analysis import report

    console = _console()
    record, result, stored = load(file, compare_model=False)
    _warn_open(record)
    console.print(report.run_table(record))
    console.print(report.steps_table(record))
    for renderable in report.analysis_renderables(result):
        console.print(renderable)
    _computed_note(stored)


@click.command()
@click.argument("file", type=FILE)
@click.option(
    "-o",
    "--out",
    "out",
    type=click.Path(dir_okay=False, path_type=Path),
    required=True,
    help="The image to write (PNG; the suffix picks the format).",
)
@click.option(
    "--overwrite",
    is_flag=True,
    help="Replace an HDF5 file (a run file) at the output path; without it one is refused.",
)
def plot(file: Path, out: Path, overwrite: bool) -> None:
    """Plot a run as in the paper's Figure 2C: mean p-v and l-v with their spread, each
    repetition faint, the model dashed, the transitions marked."""
    from labrig.analysis.experiments import force_for_run
    from labrig.analysis.plot import plot_run
    from labrig.user_files import check_output_path

    check_output_path(out, "-o", overwrite=overwrite)

    record, result, stored = load(file)
    _warn_open(record)
    force = force_for_run(file)
    plot_run(result, out, force=force)
    curves = "p-v and l-v" if result.with_length else "p-v"
    if force is not None:
        curves += " and force-v"
    click.echo(f"{out}: {curves} of {file} ({len(result.repetitions)} repetitions)")
    _computed_note(stored)


@click.command()
@click.argument("file", type=FILE)
@click.option(
    "--csv",
    "directory",
    type=click.Path(file_okay=False, path_type=Path),
    required=True,
    help="Folder for the CSV files (created if needed).",
)
@click.option(
    "--overwrite",
    is_flag=True,
    help="Replace an HDF5 file (a run file) among the CSV files' names; without it one is refused.",
)
def export(file: Path, directory: Path, overwrite: bool) -> None:
    """Export a run's raw series and its averaged curves as CSV (units in the column
    names)."""
    from labrig.analysis.export import export_csv
    from labrig.user_files import check_output_path, check_shown_name

    if directory.exists() and not directory.is_dir():
        raise InputError(f"--csv {directory}: exists and is not a folder")
    check_shown_name(directory, "--csv")
    for old in sorted(directory.glob("*.csv")) if directory.is_dir() else ():
        check_output_path(old, "--csv", overwrite=overwrite)  # its names are rewritten
    record, result, stored = load(file)
    _warn_open(record)
    written = export_csv(record, result, directory)
    click.echo(f"{directory}: {len(written)} CSV files from {file}")
    _computed_note(stored)


@click.command("compare")
@click.argument("file", type=FILE)
@click.option(
    "--segments",
    "segments",
    multiple=True,
    metavar="SEG",
    help="Compare with these segments instead of the protocol's specimen (repeat the "
    "option per segment): library names, measured segments, CSV paths.",
)
@click.option(
    "--library",
    "library",
    type=click.Path(file_okay=False, path_type=Path),
    help="Folder of measured segments (default $LABRIG_LIBRARY or ./library).",
)
@click.option("--store", is_flag=True, help="Store this analysis in the run file.")
@click.option(
    "--json",
    "as_json",
    is_flag=True,
    help='Print the comparison as one JSON object: {"rmse": {...}, "transitions": [...], '
    '"paper_transitions": [...], "unpredicted": [...]} (the model\'s events, and its '
    "transitions as the paper counts them: the events at one supplied volume are one). "
    'A specimen with no model: "no_model" (the reason) and the rest empty.',
)
def compare_command(
    file: Path, segments: tuple[str, ...], library: Path | None, store: bool, as_json: bool
) -> None:
    """Compare a run with the stability model: RMSE of pressure and length against the
    mean, and predicted against measured transitions. A run whose specimen has no model
    (specimen.model: none) is compared only with segments named by --segments."""
    from labrig.analysis import report
    from labrig.analysis.analyse import analyse
    from labrig.analysis.results import write_analysis

    console = _console()
    record, result, stored = load(file)
    if not segments and not record.protocol.specimen.has_model:
        _no_model(file, record, result, store, as_json)
        return
    if segments or library is not None or store or result.comparison is None:
        # the specimen's own segments unless others are named; a segment that cannot be
        # loaded is an error here, not a note
        names = list(segments) or list(record.protocol.specimen.segments)
        result = analyse(file, segments=names, library_dir=library, record=record)
        stored = False
    if store:
        write_analysis(file, result)
        stored = True
    if not as_json:
        _warn_open(record)
    if result.comparison is None:
        raise InputError(f"{file}: no comparison with the model ({'; '.join(result.notes)})")
    if as_json:
        import json

        from labrig.analysis.experiments import experiment_fields

        click.echo(json.dumps(experiment_fields(file, report.comparison_json(result))))
        return
    console.print(report.transitions_table(result))
    for renderable in report.comparison_tables(result):
        console.print(renderable)
    if store:
        click.echo(f"stored in {file} (/entry/analysis)")
    _computed_note(stored)


def _no_model(file: Path, record, result, store: bool, as_json: bool) -> None:
    """``compare`` of a run whose specimen has no model (``specimen.model: none``): one
    line saying so (exit 0: nothing is wrong), or the JSON with ``no_model``."""
    from labrig.analysis import report
    from labrig.analysis.analyse import NO_MODEL_NOTE
    from labrig.analysis.results import write_analysis

    if store:
        write_analysis(file, result)
    if as_json:
        import json

        from labrig.analysis.experiments import experiment_fields

        click.echo(json.dumps(experiment_fields(file, report.no_model_json(NO_MODEL_NOTE))))
        return
    _warn_open(record)
    click.echo(f"{file}: {NO_MODEL_NOTE}")
    if store:
        click.echo(f"stored in {file} (/entry/analysis)")


@click.command()
@click.argument("file", type=FILE)
@click.option("--no-analysis", is_flag=True, help="Only repair; do not analyse.")
def recover(file: Path, no_analysis: bool) -> None:
    """Make a file left by a killed run readable by anything: clear the writer's "open"
    flag, mark the unfinished run aborted, and store its analysis."""
    from labrig.analysis.recovery import recover_run

    for line in recover_run(file, analyse=not no_analysis):
        click.echo(line)
