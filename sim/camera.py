"""A simulated camera looking at the specimen: two dark dots on a light band.

``SimCamera`` renders 8-bit BGR frames (1280x720 by default) in which the two markers sit
where a length source puts them, so the real tracker can be run and checked against
the truth. The dots are anti-aliased from their exact sub-pixel centres, then blurred,
lit by a slowly drifting light and overlaid with sensor noise.

It is also a capture: ``read()`` returns ``(ok, frame)`` like ``cv2.VideoCapture``,
paced by the shared clock at ``fps`` and rendered at the frame's time, and ``get``
answers ``CAP_PROP_POS_MSEC`` and the frame size. ``write_video`` writes frames to a
real MJPG/AVI file that ``cv2.VideoCapture`` reads back.

Only what changes is rendered: the flat background and band are filled, and only the
small patches around the dots are computed in floating point, so a frame costs about
2 ms (most of it adding the noise).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from labrig.clock import Clock

_NOISE_MARGIN_PX = 32  # noise frames are this much larger, to be read at random offsets


@dataclass(frozen=True)
class VideoTruth:
    """What a written video shows: per frame its time, the true marker centres (px,
    shape (n, 2, 2): frame, marker, x/y) and the true length."""

    t_s: np.ndarray
    centres_px: np.ndarray
    length_mm: np.ndarray


class SimCamera:
    """Renders the specimen whose marker distance is ``length_mm_at(t_s)`` millimetres.

    The markers lie on a horizontal line through the frame's centre (or ``centre_px``),
    symmetric about it, and the whole specimen sways slowly by ``sway_px``, so they are
    "fixed-ish" as on a real rig. ``lighting_drift`` is the relative amplitude of a slow
    sinusoidal change of the light (period ``drift_period_s``); ``noise_grey`` is the
    sensor noise's standard deviation in grey levels; ``blur_px`` the Gaussian blur's sigma.

    As a capture it keeps the last ``queue_frames`` exposed frames, as a V4L2 camera
    under OpenCV does (4 buffers by default): a reader that falls behind by a few
    frames gets the oldest one still queued and loses none; one further behind loses
    the frames that dropped out of the queue.
    """

    def __init__(
        self,
        clock: Clock,
        length_mm_at: Callable[[float], float],
        *,
        mm_per_px: float = 0.05,
        size: tuple[int, int] = (1280, 720),
        fps: float = 30.0,
        marker_diameter_mm: float = 1.5,
        centre_px: tuple[float, float] | None = None,
        band_height_mm: float = 12.0,
        blur_px: float = 1.0,
        noise_grey: float = 2.0,
        lighting_drift: float = 0.08,
        drift_period_s: float = 60.0,
        sway_px: float = 1.5,
        marker_bgr: tuple[int, int, int] = (40, 40, 40),
        specimen_bgr: tuple[int, int, int] = (190, 190, 190),
        background_bgr: tuple[int, int, int] = (90, 90, 90),
        seed: int | None = 0,
        queue_frames: int = 4,
    ) -> None:
        if not mm_per_px > 0 or not fps > 0 or queue_frames < 1:
            raise ValueError("SimCamera: mm_per_px and fps must be > 0, queue_frames >= 1")
        self.queue_frames = int(queue_frames)
        self.clock = clock
        self.length_mm_at = length_mm_at
        self.mm_per_px = float(mm_per_px)
        self.width, self.height = (int(v) for v in size)
        self.fps = float(fps)
        self.radius_px = 0.5 * marker_diameter_mm / mm_per_px
        cx, cy = centre_px if centre_px is not None else (self.width / 2, self.height / 2)
        self.centre_px = (float(cx), float(cy))
        self.band_half_px = 0.5 * band_height_mm / mm_per_px
        self.blur_px = float(blur_px)
        self.noise_grey = float(noise_grey)
        self.lighting_drift = float(lighting_drift)
        self.drift_period_s = float(drift_period_s)
        self.sway_px = float(sway_px)
        self.marker_bgr = np.array(marker_bgr, dtype=np.float32)
        self.specimen_bgr = np.array(specimen_bgr, dtype=np.float32)
        self.background_bgr = np.array(background_bgr, dtype=np.float32)
        self._rng = np.random.default_rng(seed)
        self._noise = self._make_noise() if self.noise_grey > 0 else None
        self.hidden_markers: set[int] = set()  # fault injection: 0 and/or 1 not drawn
        self._pos_msec = 0.0
        # streaming starts when the capture is made: no frame from before it is queued
        self._last_frame = math.ceil(clock.now() * self.fps) - 1
        self._opened = True

    # -- the truth ------------------------------------------------------------------------------

    def marker_centres_px(self, t_s: float) -> np.ndarray:
        """The true centres at time t: [[x1, y1], [x2, y2]], marker 1 on the left."""
        half_px = 0.5 * float(self.length_mm_at(t_s)) / self.mm_per_px
        sway_x = self.sway_px * math.sin(2 * math.pi * t_s / 7.3)
        sway_y = self.sway_px * math.sin(2 * math.pi * t_s / 11.9 + 1.0)
        cx, cy = self.centre_px[0] + sway_x, self.centre_px[1] + sway_y
        return np.array([[cx - half_px, cy], [cx + half_px, cy]])

    def hide_marker(self, index: int, hidden: bool = True) -> None:
        """Stop drawing marker 0 or 1 (a fallen-off or covered marker), or draw it again."""
        if index not in (0, 1):
            raise ValueError(f"SimCamera has markers 0 and 1, not {index}")
        (self.hidden_markers.add if hidden else self.hidden_markers.discard)(index)

    def light_gain(self, t_s: float) -> float:
        return 1.0 + self.lighting_drift * math.sin(2 * math.pi * t_s / self.drift_period_s)

    # -- rendering -----------------------------------------------------------------------------

    def render(self, t_s: float) -> np.ndarray:
        """The frame at time t: BGR uint8, height x width x 3."""
        gain = self.light_gain(t_s)
        centres = self.marker_centres_px(t_s)
        frame = np.empty((self.height, self.width, 3), dtype=np.uint8)
        _fill(frame, 0, 0, self.width, self.height, self.background_bgr * gain)
        ends_px = 3 * self.radius_px + 40  # the band runs a little past the markers
        x0 = max(round(centres[0, 0] - ends_px), 0)
        x1 = min(round(centres[1, 0] + ends_px), self.width)
        cy = 0.5 * (centres[0, 1] + centres[1, 1])
        y0 = max(round(cy - self.band_half_px), 0)
        y1 = min(round(cy + self.band_half_px), self.height)
        if x0 < x1 and y0 < y1:
            _fill(frame, x0, y0, x1, y1, self.specimen_bgr * gain)
        for index, (x, y) in enumerate(centres):
            if index not in self.hidden_markers:
                self._draw_dot(frame, x, y, gain)
        if self._noise is not None:
            frame = self._add_noise(frame)
        return frame

    def _draw_dot(self, frame: np.ndarray, x: float, y: float, gain: float) -> None:
        """Blend one anti-aliased, blurred dot into the frame around (x, y).

        Coverage of each pixel by the disc is a linear ramp of its centre's distance to
        the edge (the covered area for an edge parallel to the pixel's sides, close to it
        otherwise) and radially symmetric, so the dot's centroid is its true centre to
        ~1e-3 px; blurring the
        coverage is the same as blurring the image there, because the surroundings are flat.
        """
        half = math.ceil(self.radius_px + 4 * self.blur_px + 2)
        ix, iy = round(x), round(y)
        x0, y0 = max(ix - half, 0), max(iy - half, 0)
        x1, y1 = min(ix + half + 1, self.width), min(iy + half + 1, self.height)
        if x0 >= x1 or y0 >= y1:
            return  # outside the frame
        yy, xx = np.ogrid[y0:y1, x0:x1]
        distance = np.sqrt((xx - x) ** 2 + (yy - y) ** 2, dtype=np.float32)
        coverage = np.clip(self.radius_px + 0.5 - distance, 0.0, 1.0).astype(np.float32)
        if self.blur_px > 0:
            coverage = cv2.GaussianBlur(coverage, (0, 0), self.blur_px)
        patch = frame[y0:y1, x0:x1].astype(np.float32)
        marker = np.clip(self.marker_bgr * gain, 0, 255)
        c = coverage[:, :, None]
        frame[y0:y1, x0:x1] = np.clip(patch * (1 - c) + marker * c + 0.5, 0, 255).astype(np.uint8)

    def _make_noise(self) -> np.ndarray:
        """Two frames of noise, made once (about 0.1 s at 1280x720)."""
        shape = (2, self.height + _NOISE_MARGIN_PX, self.width + _NOISE_MARGIN_PX, 3)
        return np.rint(self._rng.normal(0.0, self.noise_grey, shape)).astype(np.int16)

    def _add_noise(self, frame: np.ndarray) -> np.ndarray:
        """Sensor noise read from one of two pre-made noise frames at a random offset:
        fresh-looking noise every frame for the cost of one addition."""
        k = int(self._rng.integers(2))
        dy, dx = (int(v) for v in self._rng.integers(_NOISE_MARGIN_PX, size=2))
        noise = self._noise[k, dy : dy + self.height, dx : dx + self.width]
        return cv2.add(frame, noise, dtype=cv2.CV_8U)

    # -- a capture --------------------------------------------------------------------------------

    def read(self) -> tuple[bool, np.ndarray | None]:
        """The next frame, like ``cv2.VideoCapture.read``: the oldest frame still queued
        (never the same k twice), or, with none queued, the next one when it is exposed
        at k / fps; rendered as the scene was at that time."""
        if not self._opened:
            return False, None
        exposed = math.floor(self.clock.now() * self.fps)  # the newest frame so far
        k = max(self._last_frame + 1, exposed - self.queue_frames + 1)
        self._last_frame = k
        t_s = k / self.fps
        self.clock.sleep(t_s - self.clock.now())
        self._pos_msec = 1000.0 * t_s
        return True, self.render(t_s)

    def get(self, prop_id: int) -> float:
        return {
            cv2.CAP_PROP_POS_MSEC: self._pos_msec,
            cv2.CAP_PROP_FRAME_WIDTH: float(self.width),
            cv2.CAP_PROP_FRAME_HEIGHT: float(self.height),
            cv2.CAP_PROP_FPS: self.fps,
        }.get(prop_id, 0.0)

    def isOpened(self) -> bool:
        return self._opened

    def release(self) -> None:
        self._opened = False

    # -- a video file ----------------------------------------------------------------------------

    def write_video(
        self, path: str | Path, n_frames: int, fps: float = 25.0, t0_s: float = 0.0
    ) -> VideoTruth:
        """Render ``n_frames`` at t0 + k/fps into an MJPG AVI file; return what they show."""
        path = Path(path)
        writer = cv2.VideoWriter(
            str(path), cv2.VideoWriter_fourcc(*"MJPG"), fps, (self.width, self.height)
        )
        if not writer.isOpened():
            raise OSError(f"{path}: OpenCV cannot write an MJPG AVI here")
        writer.set(cv2.VIDEOWRITER_PROP_QUALITY, 95)
        t_s = t0_s + np.arange(n_frames) / fps
        try:
            for t in t_s:
                writer.write(self.render(float(t)))
        finally:
            writer.release()
        return VideoTruth(
            t_s=t_s,
            centres_px=np.array([self.marker_centres_px(float(t)) for t in t_s]),
            length_mm=np.array([float(self.length_mm_at(float(t))) for t in t_s]),
        )


def _fill(frame: np.ndarray, x0: int, y0: int, x1: int, y1: int, bgr: np.ndarray) -> None:
    """Fill [x0, x1) x [y0, y1) with one colour (cv2 does it ~30x faster than numpy)."""
    colour = tuple(float(v) for v in np.clip(np.rint(bgr), 0, 255))
    cv2.rectangle(frame, (x0, y0), (x1 - 1, y1 - 1), colour, thickness=cv2.FILLED)
