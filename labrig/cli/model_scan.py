"""``labrig model scan``, ``scan-summary`` and ``rank``: every actuator of n segments from
a library, streamed to HDF5, what it found, and the designs with the largest snap."""

from __future__ import annotations

import gc
import math
import signal
import sys
import threading
import time
from pathlib import Path

import click

from labrig.cli.options import plot_option, table_console
from labrig.errors import InputError

_TYPE_NAMES = {True: "stable", False: "unstable"}


def print_summary(data, plot_png: Path | None = None) -> None:
    """The summary table of a scan (and its Fig. 4 if asked)."""
    from rich import box
    from rich.table import Table

    from labrig.model.scan.scan_summary import METRICS, summarise

    summary = summarise(data)
    console = table_console()
    state = "complete" if data.complete else "INCOMPLETE (--resume continues it)"
    console.print(
        f"{data.path}: n = {data.n}, {summary.actuators_done:,} of "
        f"{summary.actuators_total:,} actuators ({state}), {summary.transitions:,} "
        f"transitions (the events at one supplied volume count as one; "
        f"{summary.events:,} path events), "
        f"{summary.actuators_with_snap:,} actuators snap, {summary.failed} failed"
    )
    table = Table(box=box.SIMPLE_HEAD, pad_edge=False)
    for heading in ("direction", "(α, β)", "kind", "count", "actuators"):
        table.add_column(heading, justify="right" if heading[0] in "ca" else "left", no_wrap=True)
    for metric in METRICS:
        table.add_column(f"{metric} min … max", justify="right", no_wrap=True)
    for t in summary.types:
        table.add_row(
            "inflate" if t.direction > 0 else "deflate",
            f"({t.alpha}, {t.beta})",
            _TYPE_NAMES[t.stable],
            f"{t.count:,}",
            f"{t.actuators:,}",
            *(_span(metric, *t.ranges[metric]) for metric in METRICS),
        )
    console.print(table)
    if summary.failed:
        console.print(
            f"first failure: actuator {data.failed_actuator[0]} "
            f"({' + '.join(data.segment_names(data.failed_segments[0]))}): "
            f"{data.failed_error[0]}"
        )
    if data.elapsed_s > 0:
        console.print(
            f"computed in {data.elapsed_s:.1f} s with {data.workers} worker(s); peak memory "
            f"{data.parent_peak_rss_mib:.0f} MiB (parent), {data.worker_peak_rss_mib:.0f} MiB "
            "(largest worker)"
        )
    if plot_png is not None:
        from labrig.model.scan.scan_summary import plot_fig4

        plot_fig4(data, plot_png)
        console.print(f"plot: {plot_png}")


def _span(metric: str, lo: float, hi: float) -> str:
    if math.isnan(lo):
        return "–"
    if metric == "dE":
        return f"{lo:+.2e} … {hi:+.2e}"
    return f"{lo:+.4f} … {hi:+.4f}"


PLOT_OPTION = plot_option(
    "Draw the paper's Fig. 4 A-C (dv, dl, dp against dE) for the scan to this PNG."
)


@click.command("scan")
@click.option("--n", "n", type=int, required=True, help="Segments per actuator (2-6).")
@click.option(
    "--library",
    "library_spec",
    default="analytical",
    show_default=True,
    help="'analytical' (the 36 braided segments of the default library, bare names), "
    "'paper', 'paper-r', 'paper-gent', 'paper-clamped', 'calibrated' or 'si' (the 36 of that "
    "library, prefixed names), "
    "'gent', or a folder of measured CSV curves.",
)
@click.option(
    "--out",
    type=click.Path(dir_okay=False, path_type=Path),
    required=True,
    help="The HDF5 file the scan is streamed to.",
)
@click.option("--workers", type=int, default=None, help="Processes (default: every core).")
@click.option(
    "--scheduler",
    default=None,
    metavar="tcp://HOST:PORT",
    help="Run the chunks on this dask.distributed cluster instead of local processes "
    "(pip install 'labrig[cluster]'; docs/how-to/dask-scan.md).",
)
@click.option("--resume", is_flag=True, help="Continue an interrupted scan in --out.")
@click.option("--deflate", is_flag=True, help="Also deflate each actuator back to zero.")
@PLOT_OPTION
def scan(
    n: int,
    library_spec: str,
    out: Path,
    workers: int | None,
    scheduler: str | None,
    resume: bool,
    deflate: bool,
    plot_png: Path | None,
) -> None:
    """Every actuator of N segments from a library: the transitions of each (its path's
    events), streamed to the HDF5 file OUT as they are computed, then a summary per
    transition type, counted as the paper counts them."""
    from rich.progress import (
        BarColumn,
        MofNCompleteColumn,
        Progress,
        TextColumn,
        TimeElapsedColumn,
        TimeRemainingColumn,
    )

    from labrig.model.scan.plan import choose_solver_mode
    from labrig.user_files import check_output_path

    check_output_path(out, "--out", overwrite=None, own_kind="labrig model scan")  # no run file

    # before the solver is imported, which fixes its mode; a cluster's workers compile
    # on their own, the scan's process solves nothing
    plan = None if scheduler is not None else choose_solver_mode(library_spec, n, workers)

    from labrig.model.scan.run import run_scan
    from labrig.model.scan.scan import ScanInterrupted, load_library
    from labrig.model.scan.scan_file import read_scan

    if scheduler is not None:
        import logging

        # dask logs a lost connection with its traceback; the scan says it in one line
        logging.getLogger("distributed").setLevel(logging.CRITICAL)
    compiling = None
    if plan is not None and plan.compiles_now:
        from labrig.model.scan.background_compile import COMPILED, REFERENCE, compile_beside
        from labrig.model.scan.plan import named_library
        from labrig.model.scan.run import check_out

        check_out(out, resume=resume)  # a scan refused compiles nothing
        print("compiling the solver once for this install (~1 min)...", file=sys.stderr)
        # while the library's tables are built here
        compiling = compile_beside(COMPILED if named_library(library_spec) else REFERENCE)
    library = load_library(library_spec)
    if compiling is not None:
        compiling.wait()  # then the workers load its machine code from numba's cache
    columns = (
        TextColumn(f"n = {n}"),
        BarColumn(),
        MofNCompleteColumn(),
        TextColumn("{task.fields[rate]}"),
        TimeElapsedColumn(),
        TextColumn("left"),
        TimeRemainingColumn(),
    )
    # no refresh thread: the pool forks after the bar exists, and a fork must not copy a
    # running thread; the bar is redrawn on every finished chunk instead
    with Progress(*columns, auto_refresh=False, console=table_console(), transient=False) as bar:
        task = bar.add_task("scan", total=None, rate="")
        drawn = 0.0  # when the bar was last drawn

        def show(p) -> None:
            nonlocal drawn
            speed = bar.tasks[0].speed
            rate = f"{speed:,.0f} actuators/s" if speed else ""
            bar.update(task, completed=p.actuators_done, total=p.actuators_total, rate=rate)
            # drawn ten times a second at most: rich's drawing of every chunk (199 at
            # n = 3) was 1.1 s of a profiled scan's parent
            now = time.monotonic()
            if now - drawn >= 0.1 or p.actuators_done == p.actuators_total:
                drawn = now
                bar.refresh()

        stop = threading.Event()

        def on_ctrl_c(signum, frame) -> None:
            if stop.is_set():  # the second Ctrl-C: now
                raise KeyboardInterrupt
            stop.set()

        previous = signal.signal(signal.SIGINT, on_ctrl_c)
        try:
            run_scan(
                library,
                n,
                out,
                workers=workers,
                resume=resume,
                deflate=deflate,
                progress=show,
                stop=stop,
                scheduler=scheduler,
            )
        except (ScanInterrupted, KeyboardInterrupt):
            bar.stop()
            click.echo(
                f"interrupted: the finished chunks are in {out}; the same command with "
                "--resume continues it",
                err=True,
            )
            raise click.Abort() from None
        finally:
            signal.signal(signal.SIGINT, previous)
    print_summary(read_scan(out), plot_png)
    if plan is not None and not plan.compiled and not plan.cached:
        _compile_for_the_next_scan()
    # The scan is done and so, from the shell, is the process: its objects (numba's,
    # hundreds of thousands) need not be collected one by one as the interpreter exits,
    # which took 0.4 s of a warm n = 3 scan and 1.3-1.5 s after a compile
    # (tests/benchmarks/bench_scan_wall.py). Frozen, they are freed with the process;
    # only garbage in cycles outlives it in a caller that goes on.
    gc.freeze()


def _compile_for_the_next_scan() -> None:
    """After a scan in plain Python on an empty cache: the compile at the lowest priority,
    so that a larger scan later finds the solver compiled."""
    from labrig.model.scan import background_compile

    if background_compile.start():
        click.echo(
            "compiling the solver in the background, at the lowest priority, for the next "
            "larger scan",
            err=True,
        )


@click.command("scan-summary")
@click.argument("scan_file", type=click.Path(dir_okay=False, path_type=Path))
@PLOT_OPTION
def scan_summary(scan_file: Path, plot_png: Path | None) -> None:
    """Per transition type of the scan in SCAN_FILE (as the paper counts transitions):
    the count and the ranges of dE, dv, dl, dp."""
    from labrig.model.scan.scan_file import read_scan

    print_summary(read_scan(scan_file), plot_png)


@click.command("rank")
@click.argument("scan_file", type=click.Path(dir_okay=False, path_type=Path))
@click.option("--by", type=click.Choice(["dl", "dv", "dp", "dE"]), default="dl", show_default=True)
@click.option("--top", type=int, default=20, show_default=True)
def rank(scan_file: Path, by: str, top: int) -> None:
    """The designs of SCAN_FILE with the largest snap by a metric (its magnitude): one
    row per actuator, with the transition (as the paper counts them) that has it."""
    from rich import box
    from rich.table import Table

    from labrig.model.scan.scan_file import read_scan
    from labrig.model.scan.scan_summary import METRICS, rank_designs

    if top < 1:
        raise InputError(f"--top {top}: must be at least 1")
    data = read_scan(scan_file)
    designs = rank_designs(data, by, top)
    table = Table(
        title=f"{scan_file}: the {len(designs)} designs with the largest |{by}|",
        box=box.SIMPLE_HEAD,
        pad_edge=False,
    )
    for heading in ("#", "segments", "v (mL)", "direction", "(α, β)", "kind", *METRICS):
        table.add_column(
            heading + (" ◂" if heading == by else ""),
            justify="left" if heading in ("segments", "direction", "kind") else "right",
            no_wrap=True,
        )
    for d in designs:
        table.add_row(
            str(d.rank),
            " + ".join(d.segments),
            f"{d.v_ml:.3f}",
            "inflate" if d.direction > 0 else "deflate",
            f"({d.alpha}, {d.beta})",
            _TYPE_NAMES[d.stable],
            *(f"{d.metrics[m]:+.2e}" if m == "dE" else f"{d.metrics[m]:+.4f}" for m in METRICS),
        )
    table_console().print(table)
