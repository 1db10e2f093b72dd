"""Benchmark: marker tracking speed and accuracy on rendered 1280x720 frames.

Run: python tests/benchmarks/bench_tracking.py [--write-docs]

Everything runs on one core (cv2.setNumThreads(1)). Frames are rendered first, so the
tracking times exclude rendering; the rendering cost per frame is printed too. Errors
are against SimCamera's exact truth at 0.05 mm/px.
"""

from __future__ import annotations

import argparse
import math
import sys
import tempfile
import time
from pathlib import Path

import cv2
import numpy as np

from labrig.cli.performance_doc import add_write_docs_argument, markdown_table, script_doc
from labrig.drivers.camera import CameraLength, FrameSource
from labrig.drivers.markers import MarkerTracker
from labrig.sim.camera import SimCamera
from labrig.time.virtual import VirtualClock

N_FRAMES = 200
MM_PER_PX = 0.05


def length_mm_at(t_s: float) -> float:
    return 40.0 + 5.0 * math.sin(0.7 * t_s)


def scene(noise_grey: float, blur_px: float) -> SimCamera:
    return SimCamera(
        VirtualClock(),
        length_mm_at,
        mm_per_px=MM_PER_PX,
        noise_grey=noise_grey,
        blur_px=blur_px,
        lighting_drift=0.15,
        drift_period_s=5.0,
        seed=1,
    )


def errors(fixes, cam, t_s):
    est = np.array([[[f.x1_px, f.y1_px], [f.x2_px, f.y2_px]] for f in fixes])
    truth = np.array([cam.marker_centres_px(t) for t in t_s])
    px = np.hypot(*(est - truth).transpose(2, 0, 1))  # per marker, per frame
    mm = np.array([f.distance_px * MM_PER_PX for f in fixes]) - [length_mm_at(t) for t in t_s]
    return px, mm


def per_frame_s(fn, frames, repeats: int = 3) -> float:
    """Seconds per frame, the best of a few passes (the machine is shared)."""
    best = math.inf
    for _ in range(repeats):
        started = time.perf_counter()
        for frame in frames:
            fn(frame)
        best = min(best, (time.perf_counter() - started) / len(frames))
    return best


def main() -> None:
    parser = argparse.ArgumentParser()
    add_write_docs_argument(parser)
    doc = script_doc(["tracking"], parser.parse_args().write_docs)
    cv2.setNumThreads(1)
    t_s = np.arange(N_FRAMES) / 30.0
    rows = []
    for noise_grey, blur_px in ((2.0, 1.0), (5.0, 2.0)):
        cam = scene(noise_grey, blur_px)
        frames = [cam.render(float(t)) for t in t_s]
        render_ms = per_frame_s(cam.render, t_s[:50]) * 1e3

        tracker = MarkerTracker()
        fixes = [tracker.track(f) for f in frames]  # the accuracy pass
        roi_s = per_frame_s(tracker.track, frames)
        full = MarkerTracker()

        def full_search(frame, tr=full):
            tr.reset()
            tr.track(frame)

        full_s = per_frame_s(full_search, frames)
        px, mm = errors(fixes, cam, t_s)
        rows.append(
            (
                f"noise {noise_grey:g} grey levels, blur σ {blur_px:g} px",
                1 / roi_s,
                1 / full_s,
                np.sqrt(np.mean(px**2)),
                np.max(px),
                np.sqrt(np.mean(mm**2)),
                np.max(np.abs(mm)),
                sum(f.ok for f in fixes) / N_FRAMES,
                render_ms,
            )
        )

    # The same scene written to an MJPG/AVI and read back through cv2.VideoCapture.
    cam = scene(2.0, 1.0)
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "bench.avi"
        truth = cam.write_video(path, n_frames=N_FRAMES, fps=30.0)
        length = CameraLength(FrameSource.open_file(path), mm_per_px=MM_PER_PX)
        started = time.perf_counter()
        samples = []
        while (s := length.read()) is not None:
            samples.append(s)
        file_s = (time.perf_counter() - started) / len(samples)
        length.close()
    est = np.array([[[s.x1_px, s.y1_px], [s.x2_px, s.y2_px]] for s in samples])
    px = np.hypot(*(est - truth.centres_px).transpose(2, 0, 1))
    mm = np.array([s.length_mm for s in samples]) - truth.length_mm
    rows.append(
        (
            "MJPG file read back (decode + track)",
            1 / file_s,
            float("nan"),
            np.sqrt(np.mean(px**2)),
            np.max(px),
            np.sqrt(np.mean(mm**2)),
            np.max(np.abs(mm)),
            sum(s.ok for s in samples) / len(samples),
            float("nan"),
        )
    )

    print(f"marker tracking, 1280x720, {MM_PER_PX} mm/px, one core, {N_FRAMES} frames")
    print(f"python {sys.version.split()[0]}, opencv {cv2.__version__}, numpy {np.__version__}")
    header = (
        "case (1280x720, 0.05 mm/px)",
        "fps (ROI)",
        "fps (full frame)",
        "centroid error rms / max (px)",
        "length error rms / max (mm)",
        "tracked",
        "render (ms per frame)",
    )
    table = [
        (
            name,
            f"{fps_roi:.0f}",
            "-" if math.isnan(fps_full) else f"{fps_full:.0f}",
            f"{px_rms:.3f} / {px_max:.3f}",
            f"{mm_rms:.4f} / {mm_max:.4f}",
            f"{ok:.1%}",
            "-" if math.isnan(render) else f"{render:.2f}",
        )
        for name, fps_roi, fps_full, px_rms, px_max, mm_rms, mm_max, ok, render in rows
    ]
    doc.publish("tracking", markdown_table(header, table, right={1, 2, 3, 4, 5, 6}))


if __name__ == "__main__":
    main()
