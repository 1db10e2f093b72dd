"""``labrig track``: marker tracking on a recorded video, one CSV row per frame."""

from __future__ import annotations

import sys
import time
from pathlib import Path

import click

from labrig.errors import InputError

CSV_HEADER = "t_s,x1_px,y1_px,x2_px,y2_px,length_mm,ok"


@click.command()
@click.argument("video", type=click.Path(dir_okay=False, path_type=Path))
@click.option("--mm-per-px", type=float, help="Scale in the markers' plane, mm per pixel.")
@click.option(
    "--reference-distance-mm",
    type=float,
    help="Scale from the first frame: its markers are this far apart, in mm.",
)
@click.option(
    "--out",
    type=click.Path(dir_okay=False, path_type=Path),
    help="Write the CSV here (default: standard output).",
)
@click.option(
    "--overwrite",
    is_flag=True,
    help="Replace an HDF5 file (a run file) at the output path; without it one is refused.",
)
def track(
    video: Path,
    mm_per_px: float | None,
    reference_distance_mm: float | None,
    out: Path | None,
    overwrite: bool,
) -> None:
    """Track the two markers in VIDEO and write the specimen's length for every frame.

    CSV columns: t_s,x1_px,y1_px,x2_px,y2_px,length_mm,ok (ok is 1 or 0; a frame
    whose markers were lost or merged has NaN positions and length). Prints the
    frames per second and the fraction of frames tracked.
    """
    from labrig.drivers.camera import CameraLength, FrameSource

    if (mm_per_px is None) == (reference_distance_mm is None):
        raise InputError("track: give exactly one of --mm-per-px S and --reference-distance-mm D")
    if out is not None:
        from labrig.user_files import check_output_path

        check_output_path(out, "--out", overwrite=overwrite)
    started = time.perf_counter()
    length = CameraLength(
        FrameSource.open_file(video),
        mm_per_px=mm_per_px,
        reference_distance_mm=reference_distance_mm,
    )
    try:
        # The first frame is read before anything is written: a video that cannot be
        # read or calibrated leaves no half-written CSV behind.
        sample = length.read()
        try:
            sink = out.open("w", encoding="utf-8") if out is not None else sys.stdout
        except OSError as exc:
            raise InputError(f"--out {out}: cannot write it ({exc.strerror})") from exc
        n_frames = n_ok = 0
        try:
            sink.write(CSV_HEADER + "\n")
            while sample is not None:
                n_frames += 1
                n_ok += sample.ok
                sink.write(
                    f"{sample.t_s:.6f},{sample.x1_px:.4f},{sample.y1_px:.4f},"
                    f"{sample.x2_px:.4f},{sample.y2_px:.4f},{sample.length_mm:.5f},"
                    f"{int(sample.ok)}\n"
                )
                sample = length.read()
        finally:
            if out is not None:
                sink.close()
    finally:
        length.close()
    elapsed_s = time.perf_counter() - started
    click.echo(
        f"{n_frames} frames in {elapsed_s:.2f} s: {n_frames / elapsed_s:.0f} frames/s; "
        f"markers tracked in {n_ok} ({100.0 * n_ok / n_frames:.1f} %)",
        err=out is None,
    )
