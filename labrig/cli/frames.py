"""``labrig frames RUN.h5 (--at-transitions | --at-volumes V,V,...) -o STRIP.png``:
frames of the run's video before and after each measured transition, or at chosen
volumes, annotated with the markers, the length, the volume and the pressure."""

from __future__ import annotations

from pathlib import Path

import click

from labrig.cli.review import RunFileArgument
from labrig.errors import InputError


def _volumes(text: str | None) -> list[float] | None:
    if text is None:
        return None
    try:
        volumes = [float(part) for part in text.split(",") if part.strip()]
    except ValueError:
        raise InputError(f"--at-volumes {text}: give volumes in mL, e.g. 10,20,30") from None
    if not volumes or any(not v > 0 for v in volumes):
        raise InputError(f"--at-volumes {text}: give volumes in mL above 0, e.g. 10,20,30")
    return volumes


@click.command()
@click.argument("file", type=RunFileArgument())
@click.option("--at-transitions", is_flag=True, help="Before and after each measured transition.")
@click.option("--at-volumes", metavar="V,V,...", help="Where the inflation reaches these mL.")
@click.option("--repetition", type=int, help="Repetition for --at-volumes (default the last).")
@click.option(
    "-o",
    "--out",
    type=click.Path(dir_okay=False, path_type=Path),
    required=True,
    help="The strip image (PNG).",
)
@click.option(
    "--overwrite",
    is_flag=True,
    help="Replace an HDF5 file (a run file) at the output path; without it one is refused.",
)
def frames(
    file: Path,
    at_transitions: bool,
    at_volumes: str | None,
    repetition: int | None,
    out: Path,
    overwrite: bool,
) -> None:
    """Frames of the run's video as a strip: the paper's snapshot figures."""
    if at_transitions == (at_volumes is not None):
        raise InputError("labrig frames: give exactly one of --at-transitions and --at-volumes")
    volumes = _volumes(at_volumes)
    from labrig.user_files import check_output_path

    check_output_path(out, "-o", overwrite=overwrite)
    from labrig.analysis import frame_strip
    from labrig.analysis.runfile import load_run

    record = load_run(file)
    video = frame_strip.video_index(file)
    if at_transitions:
        from labrig.cli.review import load

        _, result, _ = load(file, compare_model=False)
        tiles = frame_strip.transition_tiles(record, result, video)
        columns = 2
    else:
        tiles = frame_strip.volume_tiles(record, video, volumes, repetition)
        columns = len(tiles)
    image = frame_strip.write_strip(record, video, tiles, columns, out)
    click.echo(
        f"{out}: {len(tiles)} frames of {video.path.name} ({image.shape[1]}x{image.shape[0]})"
    )
