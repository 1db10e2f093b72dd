"""``labrig model path SEG SEG [SEG ...]``: the quasi-static path of a combined actuator
and its transitions, as a table, JSON or a plot.

With ``--deflate`` the path is inflation to the end volume followed by deflation back to
zero (the rig withdraws between repetitions, so the hysteresis matters): the path arrays
run up and then down in volume, and every transition says in which direction it
happened. The table counts transitions as the paper does (the events at one supplied
volume are one, their relative changes compounded,
``labrig.model.actuator.paper_counting``); ``--json`` gives both the
path's events (``transitions``) and that counting (``paper_transitions``). Without
``--v-end-ml`` inflation ends where no further transition is possible
(``labrig.model.actuator.path.default_end_volume_ml``).
"""

from __future__ import annotations

import json
import time
from pathlib import Path

import click

from labrig.cli.options import plot_option, table_console
from labrig.errors import InputError


def _table(names, found, v_end_ml: float, seconds: float) -> None:
    from rich import box
    from rich.table import Table

    from labrig.model.actuator.paper_counting import paper_transitions

    counted = paper_transitions(found)
    table = Table(
        title=f"{' + '.join(names)}: transitions (inflation to {v_end_ml:.2f} mL)",
        box=box.SIMPLE_HEAD,
        pad_edge=False,
    )
    headings = ("direction", "v (mL)", "(α, β)", "kind", "events", "dE", "dv", "dl", "dp")
    for heading in headings:
        left = heading in ("direction", "kind", "events")
        table.add_column(heading, justify="left" if left else "right", no_wrap=True)
    for t in counted:
        table.add_row(
            t.direction_name,
            f"{t.v_ml:.3f}",
            f"({t.alpha}, {t.beta})",
            "stable" if t.stable else "unstable",
            "+".join("crossing" if e.stable else "snap" for e in t.events),
            f"{t.dE:+.2e}",
            f"{t.dv:+.3f}",
            f"{t.dl:+.4f}",
            f"{t.dp:+.4f}",
        )
    console = table_console()
    console.print(table)
    console.print(
        f"{len(counted)} transitions as the paper counts them (the events at one supplied "
        f"volume are one; {len(found)} events); path computed in {seconds * 1e3:.1f} ms"
    )


@click.command("path")
@click.argument("segs", nargs=-1, metavar="SEG SEG [SEG ...]")
@click.option("--deflate", is_flag=True, help="After inflating, deflate back to zero (hysteresis).")
@click.option("--v-end-ml", type=float, default=None, help="End volume of inflation (mL).")
@click.option(
    "--json",
    "as_json",
    is_flag=True,
    help="Print the path, its events (transitions) and the transitions as the paper counts "
    "them (paper_transitions) as one JSON object.",
)
@plot_option("Write p-v, l-v (and for two segments the v1-v2 plane) to this PNG.")
def path(
    segs: tuple[str, ...],
    deflate: bool,
    v_end_ml: float | None,
    as_json: bool,
    plot_png: Path | None,
) -> None:
    """The quasi-static path of the actuator made of the segments SEG (library names
    such as B46-T20, gent-a/b/c, or CSV files), with its transitions (as the paper
    counts them: the events at one supplied volume are one)."""
    if len(segs) < 2:
        raise InputError(
            f"model path needs at least two segments, got {len(segs)}: e.g. B46-T20 B46-T22"
        )
    from labrig.model.path_document import checked_end_volume_ml, path_document, solve_path

    v_end_ml = checked_end_volume_ml(v_end_ml, named="--v-end-ml")
    from labrig.model.segments.catalog import load_segment

    curves = [load_segment(s) for s in segs]
    started = time.perf_counter()
    found_path, sampled, found = solve_path(curves, v_end_ml, deflate=deflate)
    seconds = time.perf_counter() - started
    names = found_path.actuator.names
    if plot_png is not None:
        from labrig.model.plots import plot_path

        plot_path(found_path, sampled, found, plot_png)
    if as_json:
        click.echo(json.dumps(path_document(names, sampled, found)))
        return
    _table(names, found, found_path.v_end_ml, seconds)
    if plot_png is not None:
        click.echo(f"plot: {plot_png}")
