"""``labrig model``: the stability model from the command line (curves, paths, scans)."""

from __future__ import annotations

import click

from labrig.cli import LazyGroup

# name -> ("module", "attribute"), imported on first use.
MODEL_COMMANDS: dict[str, tuple[str, str]] = {
    "calibrate": ("labrig.cli.model_paper", "calibrate"),
    "curve": ("labrig.cli.model_curve", "curve"),
    "paper": ("labrig.cli.model_paper", "paper"),
    "path": ("labrig.cli.model_path", "path"),
    "rank": ("labrig.cli.model_scan", "rank"),
    "scan": ("labrig.cli.model_scan", "scan"),
    "scan-summary": ("labrig.cli.model_scan", "scan_summary"),
}


@click.group(cls=LazyGroup, lazy_commands=MODEL_COMMANDS)
def model() -> None:
    """Predict segments and combined actuators with the stability model."""
