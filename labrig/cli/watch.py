"""``labrig watch``: the live page for a run that another process is recording."""

from __future__ import annotations

from pathlib import Path

import click


@click.command()
@click.argument("run_file", type=click.Path(dir_okay=False, path_type=Path))
@click.option(
    "--live-port",
    type=click.IntRange(0, 65535),
    default=0,
    help="Port of the live view on 127.0.0.1 (default: any free port).",
)
@click.option(
    "--live-hold",
    type=click.FloatRange(min=0.0),
    default=None,
    help="Seconds to keep serving once the run has ended (default: until Ctrl-C).",
)
def watch(run_file: Path, live_port: int, live_hold: float | None) -> None:
    """Serve the live page of RUN_FILE while it is recorded (read-only: SWMR)."""
    from labrig.live.follow import FileFollower, open_growing, protocol_of
    from labrig.live.session import LiveView

    run = open_growing(run_file)
    try:
        protocol, title = protocol_of(run)
        view = LiveView(protocol, live_port, title).start()
    except BaseException:
        run.close()
        raise
    click.echo(f"live view: {view.url}", err=True)
    follower = FileFollower(run, view.state, protocol)
    try:
        status = follower.follow()
        click.echo(f"the run has ended: {status}", err=True)
        view.close(float("inf") if live_hold is None else live_hold)
    except KeyboardInterrupt:
        view.close()
    finally:
        if run.id.valid:
            run.close()
