"""Options that several commands share, declared once."""

from __future__ import annotations

from pathlib import Path

import click

from labrig.errors import InputError


def _existing_folder(_ctx, _param, value: Path | None) -> Path | None:
    # checked while the options are read, before a command spends seconds on its work
    if value is not None and not value.parent.is_dir():
        raise InputError(f"--plot {value}: the folder {value.parent} does not exist")
    return value


def plot_option(help_text: str):
    """``--plot FILE`` (the parameter ``plot_png``): a figure to write, in a folder that
    must already exist."""
    return click.option(
        "--plot",
        "plot_png",
        type=click.Path(dir_okay=False, path_type=Path),
        callback=_existing_folder,
        help=help_text,
    )


def table_console():
    """A console for tables; when the output is not a terminal (a pipe, a file, a test)
    it is wide enough for them, which rich would otherwise squeeze into 80 columns."""
    from rich.console import Console

    console = Console()
    return console if console.is_terminal else Console(width=160)
