"""``labrig runs DIR``: a campaign of run files as one table (``labrig.open_runs``).

One row per run: what was run, how it ended, and each snap-through the model predicts
(counted as the paper counts them: ``compare --json``'s ``paper_transitions`` of type
``snap``) with the measured volume, pressure and length jumps, the model's and the error
(``labrig.api.campaign``). ``--json`` prints ``{"runs": [row, ...]}`` (null for a
missing value), ``--csv FILE`` writes the same table; both carry every column.
"""

from __future__ import annotations

import json
from pathlib import Path

import click


def _cell(value) -> str:
    if value is None:
        return "-"
    if isinstance(value, float):
        return f"{value:.2f}"
    return str(value)


def _snap_text(row: dict, k: int) -> str:
    """One snap as 'inflate: v 23.90 (23.97) dp -44.85 (-45.89) dl 4.51 (4.44)'."""
    parts = []
    for short, unit in (("v", "ml"), ("dp", "kpa"), ("dl", "mm")):
        seen, model = row.get(f"snap{k}_{short}_{unit}"), row.get(f"snap{k}_{short}_model_{unit}")
        parts.append(f"{short} {_cell(seen)} ({_cell(model)})")
    return f"{row[f'snap{k}_phase']}: " + " ".join(parts)


def _table(rows: list[dict]):
    from rich import box
    from rich.table import Table

    table = Table(box=box.SIMPLE_HEAD, pad_edge=False, title="runs")
    for heading in ("file", "specimen", "seed", "date", "status"):
        table.add_column(heading, no_wrap=True)
    # the one column that wraps: a run's snaps, one a line
    table.add_column("snaps: measured (model)", overflow="fold")
    for row in rows:
        count = sum(1 for key in row if key.endswith("_phase") and row[key] is not None)
        snaps = "\n".join(_snap_text(row, k) for k in range(1, count + 1))
        table.add_row(
            Path(row["file"]).name,
            _cell(row.get("specimen")),
            _cell(row.get("seed")),
            _cell(row.get("date"))[:16].replace("T", " "),
            _cell(row.get("status")) if not row.get("error") else f"error: {row['error']}",
            snaps or "-",
        )
    return table


@click.command()
@click.argument("runs", nargs=-1, required=True, metavar="DIR|FILE|GLOB...")
@click.option("--json", "as_json", is_flag=True, help='Print {"runs": [row, ...]} as JSON.')
@click.option(
    "--csv",
    "csv_path",
    type=click.Path(dir_okay=False, path_type=Path),
    help="Write the table as CSV (one row per run, every column).",
)
@click.option(
    "--overwrite",
    is_flag=True,
    help="Replace an HDF5 file (a run file) at the output path; without it one is refused.",
)
def runs(runs: tuple[str, ...], as_json: bool, csv_path: Path | None, overwrite: bool) -> None:
    """A campaign as one table: each run file's protocol, specimen, seed, date and
    outcome, and each snap the model predicts (counted as the paper counts them, as in
    compare --json's paper_transitions) with its volume, dp and dl beside the model's
    and the error."""
    from labrig.api.campaign import campaign_rows, run_files
    from labrig.errors import InputError
    from labrig.recording.file_check import check_files
    from labrig.user_files import check_output_path

    if csv_path is not None:
        check_output_path(csv_path, "--csv", overwrite=overwrite)
    # every file walked by one watched child first: a damaged one becomes its row's error
    check_files(run_files(list(runs)))
    rows = campaign_rows(list(runs))
    if csv_path is not None:
        import pandas as pd

        try:
            pd.DataFrame(rows).to_csv(csv_path, index=False)
        except OSError as exc:
            raise InputError(f"--csv {csv_path}: cannot write it ({exc.strerror})") from None
    if as_json:
        click.echo(json.dumps({"runs": rows}))
        return
    from rich.console import Console

    Console(highlight=False).print(_table(rows))
    if csv_path is not None:
        click.echo(f"{csv_path}: {len(rows)} runs")
