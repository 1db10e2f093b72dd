"""Frames from a camera or a video file, each timestamped, and the specimen's length
from them: the labrig LengthSource.

``FrameSource`` wraps a ``cv2.VideoCapture`` (or any capture-like object, such as
``labrig.sim.camera.SimCamera``) and says when each frame was taken:
- a live camera: the shared clock read right after the grab returns. Backend timestamps
  are 0 or constant on several backends (hardware.md 4.4), so they are not used.
- a video file: the file's own position, ``CAP_PROP_POS_MSEC`` after the read.

``CameraLength`` = frames + ``MarkerTracker`` + a pixel-to-mm scale. The scale is given
(``mm_per_px``) or taken from the first frame, whose markers are a known distance apart
(``reference_distance_mm``). It assumes the markers move in a plane square to the
camera's axis, where one scale holds across the frame.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from labrig.clock import Clock
from labrig.devices import LengthSample
from labrig.drivers.markers import MarkerTracker, mm_per_px_from_reference
from labrig.errors import DeviceError, InputError


@dataclass(frozen=True)
class Frame:
    t_s: float
    image: np.ndarray


class FrameSource:
    """Timestamped frames from a capture. ``clock`` given: a live source stamped on the
    shared clock; ``clock=None``: a file stamped with its own position.

    ``exposure_timestamps``: a live capture whose ``CAP_PROP_POS_MSEC`` is the exposure
    time on the shared clock (SimCamera; a hardware-triggered camera could be wired the
    same way). It is then used instead of the host's reading after the grab, which is
    late by the transfer and, on a fast simulated clock, by the render time times the
    clock's speed.
    """

    def __init__(
        self,
        capture: Any,
        *,
        clock: Clock | None,
        name: str,
        exposure_timestamps: bool = False,
    ) -> None:
        self.capture = capture
        self.clock = clock
        self.name = name
        self.exposure_timestamps = exposure_timestamps
        self.n_frames = 0

    @classmethod
    def open(cls, source: int | str | Path, clock: Clock) -> FrameSource:
        """A camera (an int, or a string of digits: its device index) or a video file."""
        if isinstance(source, int) or (isinstance(source, str) and source.isdigit()):
            return cls.open_camera(int(source), clock)
        return cls.open_file(source)

    @classmethod
    def open_camera(cls, index: int, clock: Clock) -> FrameSource:
        capture = cv2.VideoCapture(index)
        if not capture.isOpened():
            raise DeviceError(
                f"camera {index} could not be opened: check that it is connected and no "
                "other program uses it, or run without hardware with --sim"
            )
        return cls(capture, clock=clock, name=f"camera {index}")

    @classmethod
    def open_file(cls, path: str | Path) -> FrameSource:
        path = Path(path)
        if not path.is_file():
            raise InputError(f"{path}: no such video file")
        capture = cv2.VideoCapture(str(path))
        if not capture.isOpened():
            raise InputError(f"{path}: OpenCV cannot read this file as a video")
        return cls(capture, clock=None, name=str(path))

    @property
    def is_file(self) -> bool:
        return self.clock is None

    def read(self) -> Frame | None:
        """The next frame; None at the end of a file."""
        ok, image = self.capture.read()
        if self.clock is not None:
            t_s = self.clock.now()  # right after the grab, before any processing
            if not ok or image is None:
                raise DeviceError(f"{self.name} returned no frame: is it still connected?")
            if self.exposure_timestamps:
                t_s = self.capture.get(cv2.CAP_PROP_POS_MSEC) / 1000.0
        else:
            if not ok or image is None:
                if self.n_frames == 0:
                    raise InputError(
                        f"{self.name}: no frame could be read (corrupt or empty video)"
                    )
                return None
            t_s = self.capture.get(cv2.CAP_PROP_POS_MSEC) / 1000.0
        self.n_frames += 1
        return Frame(t_s=t_s, image=image)

    def close(self) -> None:
        self.capture.release()


class CameraLength:
    """The specimen's length from the distance between two tracked markers."""

    def __init__(
        self,
        frames: FrameSource,
        tracker: MarkerTracker | None = None,
        *,
        mm_per_px: float | None = None,
        reference_distance_mm: float | None = None,
    ) -> None:
        if (mm_per_px is None) == (reference_distance_mm is None):
            raise InputError(
                "camera scale: give exactly one of mm_per_px and reference_distance_mm"
            )
        if mm_per_px is not None and not mm_per_px > 0:
            raise InputError(f"camera scale: mm_per_px must be > 0, got {mm_per_px}")
        self.frames = frames
        self.tracker = tracker or MarkerTracker()
        self.mm_per_px = mm_per_px
        self.reference_distance_mm = reference_distance_mm

    def read(self) -> LengthSample | None:
        frame = self.frames.read()
        if frame is None:
            return None
        fix = self.tracker.track(frame.image)
        if self.mm_per_px is None:
            # The first frame is the reference frame.
            self.mm_per_px = mm_per_px_from_reference(fix, self.reference_distance_mm)
        return LengthSample(
            t_s=frame.t_s,
            x1_px=fix.x1_px,
            y1_px=fix.y1_px,
            x2_px=fix.x2_px,
            y2_px=fix.y2_px,
            length_mm=fix.distance_px * self.mm_per_px,
            ok=fix.ok,
        )

    def close(self) -> None:
        self.frames.close()
