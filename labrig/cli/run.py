"""``labrig run``: the technician's main job — run a protocol, get one complete file."""

from __future__ import annotations

import datetime as dt
import math
import re
import time
from pathlib import Path

import click

# --speed: a stop is not paced (a SIGTERM ends a run at 0.01 within seconds:
# tests/run/test_signals_end_the_process.py); below a hundredth of real time a minute of
# rig time takes more than 100 minutes, and 1e-300 would never end. Above a million
# times real time no host keeps pace anyway.
MIN_SPEED, MAX_SPEED = 0.01, 1e6
MAX_LIVE_HOLD_S = 3600.0


def default_out_path(protocol_name: str, now: dt.datetime | None = None) -> Path:
    """runs/<date>_<time>_<protocol>.h5: sortable and readable, with a counter (-2, -3,
    ...) when another run of the same second has the name. The name is reserved
    (``reserve_new_name``): two runs started at once get two names."""
    from labrig.errors import InputError
    from labrig.recording.run_file_lock import reserve_new_name

    slug = re.sub(r"[^A-Za-z0-9]+", "-", protocol_name).strip("-").lower() or "run"
    stamp = (now or dt.datetime.now()).strftime("%Y%m%d_%H%M%S")
    folder = Path("runs")
    try:
        folder.mkdir(exist_ok=True)
    except OSError as exc:
        raise InputError(f"{folder}: cannot create the runs folder ({exc.strerror})") from None
    counter, path = 1, folder / f"{stamp}_{slug}.h5"
    while not reserve_new_name(path):
        counter += 1
        path = folder / f"{stamp}_{slug}-{counter}.h5"
    return path


@click.command()
@click.argument("protocol_file", type=click.Path(dir_okay=False, path_type=Path))
@click.option("--sim", is_flag=True, help="Run on the simulated rig, whatever the protocol says.")
@click.option(
    "--out",
    "out_path",
    type=click.Path(dir_okay=False, path_type=Path),
    help="Run file (.h5). Default: runs/<date>_<time>_<name>.h5, with -2, -3, ... when "
    "another run of the same second has that name.",
)
@click.option(
    "--overwrite",
    is_flag=True,
    help="If the run file exists, move it aside first (to FILE.replaced-<time>.h5; "
    "never deleted). Without it an existing file is refused.",
)
@click.option(
    "--speed",
    type=click.FloatRange(min=MIN_SPEED, max=MAX_SPEED),
    default=None,
    help="Simulated rig only: pace the run to X times real time (1: real time, for "
    f"training; {MIN_SPEED:g} to {MAX_SPEED:g}). Default: as fast as the machine computes "
    "it. The data are the same.",
)
@click.option(
    "--seed",
    type=click.IntRange(min=0),
    default=None,
    help="Simulated rig only: the seed of the simulation (stored in the run file); the "
    "same protocol and seed give the same data on any machine [default: 0].",
)
@click.option("--dry-run", is_flag=True, help="Check and summarise the protocol; move nothing.")
@click.option("--live", is_flag=True, help="Serve a live view of the run on 127.0.0.1.")
@click.option(
    "--live-port",
    type=click.IntRange(0, 65535),
    default=None,
    help="Port of the live view (implies --live; default: any free port).",
)
@click.option(
    "--live-hold",
    type=click.FloatRange(min=0.0, max=MAX_LIVE_HOLD_S),
    default=5.0,
    show_default=True,
    help="Seconds the live view stays up after the run (for the page to see the end).",
)
def run(
    protocol_file: Path,
    sim: bool,
    out_path: Path | None,
    overwrite: bool,
    speed,
    seed,
    dry_run: bool,
    live: bool,
    live_port: int | None,
    live_hold: float,
) -> None:
    """Run PROTOCOL_FILE on the rig and record it in one HDF5 file."""
    from labrig.cli import start_up_uncollected

    with start_up_uncollected():  # mostly the imports the checks need (scipy's)
        from labrig.config.protocol import load_protocol
        from labrig.config.rig_file import load_rig_config
        from labrig.run.dry_run import dry_run_report

        loaded = load_protocol(protocol_file)
        rig_config = load_rig_config(loaded, force_sim=sim, speed=speed, seed=seed)
        report = dry_run_report(loaded.protocol, rig_config)
    click.echo(report.text)
    if not report.ok:
        raise click.exceptions.Exit(2)
    if dry_run:
        return
    from labrig.recording.run_file_lock import claim_out_path, drop_reservation

    reserved = out_path is None
    out_path = out_path or default_out_path(loaded.protocol.name)
    live_view = None
    try:
        for line in claim_out_path(out_path, overwrite=overwrite):
            click.echo(line, err=True)
        if live or live_port is not None:
            from labrig.live.session import LiveView

            live_view = LiveView(loaded.protocol, live_port or 0).start()
            click.echo(f"live view: {live_view.url}", err=True)
        _run(loaded, rig_config, out_path, live_view)
    finally:
        if live_view is not None:
            live_view.close(live_hold)
        if reserved:
            drop_reservation(out_path)


def _run(loaded, rig_config, out_path: Path, live_view=None) -> None:
    from labrig.cli import start_up_uncollected

    with start_up_uncollected():  # mostly the drivers' imports (OpenCV, h5py, nidaqmx)
        from rich.console import Console
        from rich.progress import BarColumn, Progress, TextColumn

        from labrig.rig.assembly import build_rig
        from labrig.run.keep_awake import system_kept_awake
        from labrig.run.pump_stop import PUMP_STOP_NOT_CONFIRMED
        from labrig.run.runner import Runner, Timing

        console = Console(stderr=True)
        rig = build_rig(loaded.protocol, rig_config)
    columns = (
        TextColumn("rep {task.fields[rep]}"),
        TextColumn("[bold]{task.fields[step]:<16}"),
        BarColumn(bar_width=12),
        TextColumn("{task.fields[volume]}"),
        TextColumn("{task.fields[pressure]}"),
        TextColumn("{task.fields[length]}"),
        TextColumn("{task.fields[left]}"),
    )
    with Progress(*columns, console=console, transient=False) as progress:
        task = progress.add_task(
            "run",
            total=None,
            step="starting",
            rep="-",
            volume="",
            pressure="",
            length="",
            left="",
        )

        def show(snapshot) -> None:
            total = snapshot.elapsed_s + snapshot.remaining_s
            progress.update(
                task,
                total=total,
                completed=min(snapshot.elapsed_s, total),
                step=snapshot.step,
                rep=f"{snapshot.repetition}/{snapshot.repetitions}",
                volume=f"{snapshot.volume_ml:5.2f} mL",
                pressure=f"{snapshot.pressure_kpa:5.1f} kPa",
                length=f"{snapshot.length_mm:5.1f} mm" if math.isfinite(snapshot.length_mm) else "",
                left=f"{snapshot.remaining_s / 60:4.1f} min left",
            )
            if live_view is not None:
                live_view.state.progress(snapshot)

        wall0 = time.monotonic()
        rig_t0 = rig.clock.now()
        tap = live_view.state.tap if live_view is not None else None
        timing = Timing(signal_timeout_s=rig_config.signal_timeout_s)
        runner = Runner(loaded, rig, out_path, on_progress=show, data_tap=tap, timing=timing)
        with system_kept_awake():
            result = runner.run()
        rig_s, wall_s = rig.clock.now() - rig_t0, time.monotonic() - wall0
    if not result.stop_confirmed:
        # first, before anything else is printed: the plunger may still be moving
        console.print(f"[bold red]{PUMP_STOP_NOT_CONFIRMED}[/]", highlight=False)
    if live_view is not None:
        live_view.finish(result.status, result.reason)
    if rig.simulation is not None:
        console.print(
            f"simulated {rig_s / 60:.1f} min of rig time in {wall_s:.1f} s "
            f"(x{rig_s / max(wall_s, 1e-9):.0f} on average)"
        )
    _analyse(result.path, console)
    style = {"complete": "green", "aborted": "yellow", "faulted": "red"}[result.status]
    console.print(f"[{style}]{result.status}[/]: {result.path}")
    if result.reason:
        console.print(f"reason: {result.reason}")
    if result.status != "complete":
        raise click.exceptions.Exit(1)


def _analyse(path: Path, console) -> None:
    """Analyse the finished file and print the summary. An analysis that cannot be
    made (an aborted run with too little data) is reported, never a failed run: the
    data are in the file whatever happens here."""
    from labrig.analysis import analyse_run, summary_text
    from labrig.errors import LabrigError

    try:
        result = analyse_run(path)
    except LabrigError as exc:
        console.print(f"analysis: not made ({exc}); the raw data are in the file")
        return
    console.print(summary_text(result, width=min(console.width, 110)), end="")
