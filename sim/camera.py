"""A simulated camera looking at the specimen: two dark dots on a light band.

``SimCamera`` renders 8-bit BGR frames (1280x720 by default; grey with ``monochrome``) in
which the two markers sit where a length source puts them, so the real tracker can be run
and checked against the truth. The dots are anti-aliased from their exact sub-pixel
centres, then blurred, lit by a slowly drifting light and overlaid with sensor noise.

It is also a capture that behaves as a UVC webcam under OpenCV's V4L2 backend:
``read()`` returns ``(ok, frame)`` like ``cv2.VideoCapture``, paced by the shared clock
at ``fps``; it streams at 640x480 until a size is set; it keeps 4 buffers and hands back
the oldest; its first frames after the stream starts are dark while the auto exposure
settles; ``CAP_PROP_POS_MSEC`` is the frame's capture time on the clock (V4L2: the
kernel's monotonic buffer timestamp); ``set``/``get`` take and read back the size, rate,
exposure, focus and pixel format: it opens in YUYV, takes MJPG when asked unless it is
a YUYV-only camera (``formats``), and in YUYV gives at most the rate USB 2.0 carries
(``YUYV_BYTES_PER_S``: 10 fps at 1280x720, 30 at 640x480). As UVC webcams do, it
may be slow to deliver the first frame of a stream (``first_frame_delay_s``: 0.3-1 s
is common), and in dim light (``dim_light_fps``) its auto exposure, with
``exposure_auto_priority`` on (the default of many webcams, a control OpenCV cannot
set), lowers the real frame rate while ``CAP_PROP_FPS`` reports the nominal one. It
dies as cameras die (``stop_frames``: the next grab never returns; ``jump_clock``: its
stamps jump).
``write_video`` writes frames to a real MJPG/AVI file.

Frames are rendered where they are read (``SimFrame``): the tracker reads two small
windows per frame, and a batch of frames has its windows rendered together
(``SimFrame.stack_regions``), so a 30 fps run costs little more than a 2 fps one. A
run tracks its frames in the marker tracker's process, which draws those windows from
each frame's ``scene`` (``recipe``, ``SceneRenderer``). A video's frames are drawn by
the video's encoder process from their ``scene``
(``SceneRenderer``), and only in their rows that were not seen before: the noise is read
at offsets that are multiples of 8 pixels, so the rows away from the markers repeat
(``SimCamera.row_keys``, ``labrig.recording.jpeg_rows``).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from labrig.time.clock import Clock

from .camera_frame import SimFrame
from .camera_scene import SceneRenderer, blend, blur_matrix, fill, grey_level, to_float32

_NOISE_MARGIN_PX = 32  # noise frames are this much larger, to be read at random offsets
# ... that are multiples of a JPEG MCU's height and width: a frame's rows of MCUs away
# from the markers then repeat across frames, and a video encodes each such row once
# (``labrig.recording.jpeg_rows``); 32 offsets of 2 noise frames still look fresh at 30 fps
_NOISE_STEP_PX = 8
V4L2_DEFAULT_SIZE = (640, 480)  # what a UVC camera streams until the driver sets a size
# The light reaching the sensor in the first frames after the stream starts, while the
# auto exposure settles (a webcam's first frame is nearly black).
SETTLING_EXPOSURE = (0.0, 0.3, 0.7)
# What a UVC webcam's YUYV stream gets over USB 2.0: 1280x720 at 10 fps, 640x480 at 30
# (2 bytes a pixel), the rates such cameras list for YUYV.
YUYV_BYTES_PER_S = 1280 * 720 * 2 * 10
# How often (clock seconds) a camera whose frames stopped looks whether it was released.
STOPPED_POLL_S = 0.1


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
    ``monochrome``: a grey sensor (as machine-vision cameras are): single-channel frames,
    a third of the pixels to render, track and encode.

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
        monochrome: bool = False,
        formats: tuple[str, ...] = ("YUYV", "MJPG"),
        first_frame_delay_s: float = 0.0,
        dim_light_fps: float | None = None,
    ) -> None:
        if not mm_per_px > 0 or not fps > 0 or queue_frames < 1:
            raise ValueError("SimCamera: mm_per_px and fps must be > 0, queue_frames >= 1")
        if seed is None:  # a concrete seed: a renderer elsewhere makes the same noise
            seed = int(np.random.SeedSequence().entropy % 2**63)
        # what a renderer in another process needs to draw the same frames (``renderer``)
        self._spec = dict(
            mm_per_px=mm_per_px, size=size, marker_diameter_mm=marker_diameter_mm,
            centre_px=centre_px, band_height_mm=band_height_mm, blur_px=blur_px,
            noise_grey=noise_grey, lighting_drift=lighting_drift,
            drift_period_s=drift_period_s, sway_px=sway_px, marker_bgr=marker_bgr,
            specimen_bgr=specimen_bgr, background_bgr=background_bgr, seed=seed,
            monochrome=monochrome,
        )  # fmt: skip
        self._renderer: SceneRenderer | None = None
        self.queue_frames = int(queue_frames)
        self.channels = 1 if monochrome else 3
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
        self._dot_half_px = math.ceil(self.radius_px + 4 * self.blur_px + 2)
        # a monochrome sensor sees the colours' grey levels (OpenCV's BGR-to-grey weights)
        self.marker_bgr, self.specimen_bgr, self.background_bgr = (
            np.array(bgr if not monochrome else [grey_level(bgr)], dtype=np.float32)
            for bgr in (marker_bgr, specimen_bgr, background_bgr)
        )
        self._marker_channels, self._specimen_channels, self._background_channels = (
            bgr.tolist() for bgr in (self.marker_bgr, self.specimen_bgr, self.background_bgr)
        )
        self._rng = np.random.default_rng(seed)
        self._noise = self._make_noise() if self.noise_grey > 0 else None
        self._noise_picks: list[tuple[int, int, int]] = []  # (noise frame, dy, dx), next last
        self.hidden_markers: set[int] = set()  # fault injection: 0 and/or 1 not drawn
        self.formats = tuple(formats)
        self.fourcc = self.formats[0]  # a UVC camera opens in its first format
        self._asked_fps = float(fps)
        self.first_frame_delay_s = float(first_frame_delay_s)
        self.dim_light_fps = dim_light_fps
        self.exposure_auto_priority = True  # a V4L2 control OpenCV has no property for
        self._frames_stop_s = math.inf  # fault injection: no frame exposed from then on
        self._clock_jump_s = 0.0  # fault injection: added to every later stamp
        self._pos_msec = 0.0
        # as a capture: V4L2 streams at 640x480 until a size is set
        self.stream_size = V4L2_DEFAULT_SIZE
        self._asked_size = list(V4L2_DEFAULT_SIZE)
        self._controls = {
            cv2.CAP_PROP_AUTO_EXPOSURE: 3.0,  # V4L2: aperture-priority auto exposure
            cv2.CAP_PROP_EXPOSURE: 156.0,
            cv2.CAP_PROP_AUTOFOCUS: 1.0,
            cv2.CAP_PROP_FOCUS: 0.0,
        }
        self._restart_stream()
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
        """The frame at time t at the sensor's full size: BGR uint8, height x width x 3."""
        return np.asarray(self.frame_at(t_s))

    def frame_at(self, t_s: float, exposure: float = 1.0) -> SimFrame:
        """The frame at time t, rendered only where it is read (``SimFrame``). Everything
        random about it (the noise's pick and offset) is drawn now, so what a region
        shows does not depend on when, or whether, it is read."""
        noise = None
        if self._noise is not None:
            if not self._noise_picks:
                # drawn a block at a time: one generator call per 256 frames, not two a frame
                steps = _NOISE_MARGIN_PX // _NOISE_STEP_PX
                picks = self._rng.integers((2, steps, steps), size=(256, 3))
                picks *= (1, _NOISE_STEP_PX, _NOISE_STEP_PX)
                self._noise_picks = [tuple(pick) for pick in reversed(picks.tolist())]
            noise = self._noise_picks.pop()
        return SimFrame(
            self,
            t_s=t_s,
            gain=self.light_gain(t_s) * exposure,
            hidden=frozenset(self.hidden_markers),
            noise=noise,
        )

    def render_stack(self, frames: Sequence[SimFrame], boxes: Sequence[tuple]) -> np.ndarray:
        """The sensor-size pixels of box i (x0, y0, x1, y1: [y0:y1, x0:x1]) of frame i,
        for every i, stacked: shape (n, h, w[, 3]), the boxes all of one size. Every step
        is the one a single frame takes, done for the whole stack at once (a run tracks
        its frames in batches), so a frame's pixels are the same whichever box, and
        whichever stack, they are rendered in: a region read alone equals that region of
        the whole frame."""
        x0, y0, x1, y1 = boxes[0]
        shape = (len(frames), y1 - y0, x1 - x0, self.channels)[: 3 if self.channels == 1 else 4]
        out = np.empty(shape, dtype=np.uint8)
        if out.size == 0:
            return out
        for i, (frame, (x0, y0, x1, y1)) in enumerate(zip(frames, boxes, strict=True)):
            background, specimen, _ = frame.palette()
            band, _ = frame.layout()
            fill(out[i], 0, 0, x1 - x0, y1 - y0, background)
            bx0, by0 = max(band[0], x0), max(band[1], y0)
            bx1, by1 = min(band[2], x1), min(band[3], y1)
            if bx0 < bx1 and by0 < by1:
                fill(out[i], bx0 - x0, by0 - y0, bx1 - x0, by1 - y0, specimen)
        for index in (0, 1):  # marker 0's dot first: where the two overlap, 1 is on top
            self._draw_dots(out, frames, boxes, index)
        noisy = [i for i, frame in enumerate(frames) if frame.noise is not None]
        if noisy:
            # the noise's positive and negative parts: one saturating add, in two uint8
            # passes (a pixel's noise is one or the other), over the whole stack at once
            stack = out if len(noisy) == len(out) else out[noisy]
            flat = stack.reshape(-1, *stack.shape[2:])
            picks = [(frames[i].noise, boxes[i]) for i in noisy]
            for part, add in zip(self._noise, (cv2.add, cv2.subtract), strict=True):
                picked = [
                    part[k, dy + y0 : dy + y1, dx + x0 : dx + x1]
                    for (k, dy, dx), (x0, y0, x1, y1) in picks
                ]  # a whole frame's noise is read where it lies, not copied first
                picked = picked[0] if len(picked) == 1 else np.concatenate(picked)
                add(flat, picked, dst=flat)
            if stack is not out:
                out[noisy] = stack  # the frames' copies, made noisy
        return out

    def _render_box(self, frame: SimFrame, x0: int, y0: int, x1: int, y1: int) -> np.ndarray:
        """One frame's pixels [y0:y1, x0:x1] (``render_stack`` of one)."""
        return self.render_stack([frame], [(x0, y0, x1, y1)])[0]

    def _palette(self, gain: float) -> tuple[tuple[float, ...], tuple[float, ...], np.ndarray]:
        """Background and specimen fill colours, the markers' colour, under ``gain``:
        each channel times the gain in single precision (as numpy multiplies a float32
        colour), the fills rounded half to even; in plain Python, as a frame asks for
        it once and numpy's calls on 1-3 values cost more than the arithmetic."""
        g = to_float32(gain)
        background, specimen = (
            tuple(min(max(float(round(to_float32(c * g))), 0.0), 255.0) for c in bgr)
            for bgr in (self._background_channels, self._specimen_channels)
        )
        marker = [min(max(to_float32(c * g), 0.0), 255.0) for c in self._marker_channels]
        return background, specimen, np.array(marker, dtype=np.float32)

    def layout(self, centres: np.ndarray, hidden: frozenset) -> tuple[tuple, list]:
        """Where a frame's parts are: the specimen band's box [x0, x1) x [y0, y1) and,
        for each marker drawn, its index, its centre and its dot's box (``_dot_box``), in frame
        pixels; worked out once per frame, whichever regions are rendered."""
        (xa, ya), (xb, yb) = centres.tolist()
        ends_px = 3 * self.radius_px + 40  # the band runs a little past the markers
        cy = 0.5 * (ya + yb)
        band = (
            max(round(xa - ends_px), 0),
            max(round(cy - self.band_half_px), 0),
            min(round(xb + ends_px), self.width),
            min(round(cy + self.band_half_px), self.height),
        )
        dots = [
            (index, x, y, self._dot_box(x, y))
            for index, (x, y) in enumerate(((xa, ya), (xb, yb)))
            if index not in hidden
        ]
        return band, dots

    def _draw_dots(self, out: np.ndarray, frames, boxes, index: int) -> None:
        """Blend marker ``index``'s anti-aliased, blurred dot of frame i into stack entry
        i of ``out``, which holds box i of it (``render_stack``).

        Coverage of each pixel by the disc is a linear ramp of its centre's distance to
        the edge (the covered area for an edge parallel to the pixel's sides, close to it
        otherwise) and radially symmetric, so the dot's centroid is its true centre to
        ~1e-3 px; blurring the coverage is the same as blurring the image there, because
        the surroundings are flat. The coverage is always computed over the dot's whole
        box (then cut to the region), so every region sees the same values.
        """
        dots = [
            (i, x, y, dot, frame.palette()[2], box)
            for i, (frame, box) in enumerate(zip(frames, boxes, strict=True))
            for m, x, y, dot in frame.layout()[1]
            if m == index and dot[0] < box[2] and box[0] < dot[2] and dot[1] < box[3]
            and box[1] < dot[3]
        ]  # fmt: skip
        if not dots:
            return  # outside the region: the tracker's window on the other marker
        if len({(dot[2] - dot[0], dot[3] - dot[1]) for _, _, _, dot, _, _ in dots}) > 1:
            for dot in dots:  # a dot cut by the frame's edge has a box of its own size
                self._draw_dots_of_one_size(out, [dot])
        else:
            self._draw_dots_of_one_size(out, dots)

    def _draw_dots_of_one_size(self, out: np.ndarray, dots: list) -> None:
        """``_draw_dots`` for dots (at most one per stack entry) whose boxes have one
        size: their coverage computed all at once."""
        x, y, dx0, dy0 = np.array([(x, y, *dot[:2]) for _, x, y, dot, _, _ in dots]).T[:, :, None]
        (x0, y0, x1, y1) = dots[0][3]
        bw, bh = x1 - x0, y1 - y0
        xx = (dx0 + np.arange(bw) - x) ** 2
        yy = (dy0 + np.arange(bh) - y) ** 2
        coverage = np.sqrt(yy[:, :, None] + xx[:, None, :], dtype=np.float32)  # distance
        np.subtract(np.float32(self.radius_px + 0.5), coverage, out=coverage)
        np.maximum(coverage, 0.0, out=coverage)
        np.minimum(coverage, 1.0, out=coverage)
        if self.blur_px > 0:
            rows, cols = blur_matrix(bh, self.blur_px), blur_matrix(bw, self.blur_px)
            coverage = (rows @ coverage @ cols.T).astype(np.float32)
        if out.ndim == 4:
            coverage = coverage[..., None]
        # each dot's pixels cut to its region: read and written back through slices
        # (cheaper than gathered), blended all at once where the dots are whole
        views, cuts = [], []
        for i, _, _, (x0, y0, x1, y1), _, box in dots:
            cx0, cy0, cx1, cy1 = max(x0, box[0]), max(y0, box[1]), min(x1, box[2]), min(y1, box[3])
            views.append(out[i, cy0 - box[1] : cy1 - box[1], cx0 - box[0] : cx1 - box[0]])
            cuts.append((slice(cy0 - y0, cy1 - y0), slice(cx0 - x0, cx1 - x0)))
        markers = np.array([dot[4] for dot in dots])  # float32: (n, 3), or (n, 1) grey
        if all(view.shape[:2] == (bh, bw) for view in views):
            shape = (len(dots), 1, 1, 3) if out.ndim == 4 else (len(dots), 1, 1)
            blended = blend(np.stack(views), coverage, markers.reshape(shape))
            for view, pixels in zip(views, blended, strict=True):
                view[:] = pixels
            return
        for view, cut, c, marker in zip(views, cuts, coverage, markers, strict=True):
            view[:] = blend(view, c[cut], marker if out.ndim == 4 else marker[0])

    def _dot_box(self, x: float, y: float) -> tuple[int, int, int, int]:
        """The box [x0, x1) x [y0, y1) a dot centred at (x, y) covers, cut to the frame."""
        half = self._dot_half_px
        ix, iy = round(x), round(y)
        x0, y0 = max(ix - half, 0), max(iy - half, 0)
        return x0, y0, min(ix + half + 1, self.width), min(iy + half + 1, self.height)

    def _make_noise(self) -> tuple[np.ndarray, np.ndarray]:
        """Two frames of noise, made once (about 0.1 s at 1280x720); a frame reads one
        of them at a random offset: fresh-looking noise for the cost of one addition.
        Kept as its positive and its negative part, each uint8."""
        shape = (2, self.height + _NOISE_MARGIN_PX, self.width + _NOISE_MARGIN_PX)
        noise = np.rint(self._rng.normal(0.0, self.noise_grey, (*shape, self.channels)))
        noise = np.clip(noise if self.channels == 3 else noise[..., 0], -255, 255)
        return np.maximum(noise, 0).astype(np.uint8), np.maximum(-noise, 0).astype(np.uint8)

    def renderer(self) -> SceneRenderer:
        """A picklable stand-in for this camera's drawing: given a frame's ``scene``
        it renders the same pixels in another process (the run's video encoder, the
        marker tracker's process)."""
        if self._renderer is None:
            self._renderer = SceneRenderer(type(self), self._spec)
        return self._renderer

    def scene_frame(self, scene: tuple) -> SimFrame:
        """The frame that ``SimFrame.scene`` describes."""
        t_s, centres, gain, hidden, noise, resized_to = scene
        frame = SimFrame(self, t_s=t_s, gain=gain, hidden=frozenset(hidden), noise=noise)
        frame._centres = np.array(centres, dtype=float).reshape(2, 2)
        if resized_to is not None:
            frame.resized(resized_to)
        return frame

    def row_keys(self, frame: SimFrame, row_px: int) -> list[tuple | None] | None:
        """For each band of ``row_px`` pixel rows of the frame (the last one may be
        shorter), a key such that two bands of equal keys, of any frames of this camera,
        have equal pixels: the band's height, the fill levels, the specimen band's edges
        in it and the noise's row and offset. None where a marker's dot reaches into the
        band (drawn at sub-pixel positions: never the same twice), and None for a frame
        at another streaming size (scaled)."""
        if frame._resized_to is not None:
            return None
        background, specimen, _ = frame.palette()
        (bx0, by0, bx1, by1), dots = frame.layout()
        bx0, bx1 = max(bx0, 0), min(bx1, self.width)
        k, dy, dx = frame.noise if frame.noise is not None else (None, 0, 0)
        height = self.height
        keys: list[tuple | None] = []
        for y0 in range(0, height, row_px):
            y1 = min(y0 + row_px, height)
            if by0 < y1 and y0 < by1 and bx0 < bx1:
                band = (bx0, bx1, max(by0, y0) - y0, min(by1, y1) - y0, specimen)
            else:
                band = None
            keys.append((y1 - y0, background, band, None if k is None else (k, dy + y0, dx)))
        for *_, (_, top, _, bottom) in dots:  # the rows a dot reaches into
            for row in range(top // row_px, (bottom - 1) // row_px + 1) if top < bottom else ():
                keys[row] = None
        return keys

    # -- a capture --------------------------------------------------------------------------------

    def read(self) -> tuple[bool, SimFrame | None]:
        """The next frame, like ``cv2.VideoCapture.read`` on V4L2: the oldest frame still
        queued (never the same k twice), or, with none queued, the next one when it is
        exposed at k / fps; showing the scene as it was then, at the streaming size,
        dark while the auto-exposure settles after the stream (re)starts."""
        if not self._opened:
            return False, None
        fps = self.streaming_fps
        if not self._streaming:
            # V4L2 under OpenCV starts streaming at the first grab, not when opened:
            # no frame from before it is queued, the first comes after the camera's
            # start-up delay, and the exposure settles from then
            first_s = self.clock.now() + self.first_frame_delay_s
            self._last_frame = math.ceil(first_s * fps) - 1
            self._stream_first = self._last_frame + 1
            self._streaming = True
        exposed = math.floor(self.clock.now() * fps)  # the newest frame so far
        k = max(self._last_frame + 1, exposed - self.queue_frames + 1)
        self._last_frame = k
        t_s = k / fps
        self.clock.sleep(t_s - self.clock.now())
        while self._opened and t_s >= self._frames_stop_s:
            self.clock.sleep(STOPPED_POLL_S)  # a grab that never returns, until released
        if not self._opened:
            return False, None  # released while it waited for the frame
        self._pos_msec = 1000.0 * (t_s + self._clock_jump_s)
        settled = k - self._stream_first
        exposure = SETTLING_EXPOSURE[settled] if settled < len(SETTLING_EXPOSURE) else 1.0
        frame = self.frame_at(t_s, exposure)
        if self.stream_size != (self.width, self.height):
            frame = frame.resized(self.stream_size)
        return True, frame

    @property
    def streaming_fps(self) -> float:
        """The rate frames really come at: the one set, unless auto exposure with its
        priority on lengthens the exposure in dim light (``dim_light_fps``)."""
        auto = self._controls[cv2.CAP_PROP_AUTO_EXPOSURE] == 3.0
        if self.dim_light_fps is not None and auto and self.exposure_auto_priority:
            return min(self.fps, float(self.dim_light_fps))
        return self.fps

    def set(self, prop_id: int, value: float) -> bool:
        """Set a property as OpenCV's V4L2 backend does: the size takes a supported mode
        only (640x480 or the sensor's size) and restarts the stream; the rate, the
        exposure (``CAP_PROP_AUTO_EXPOSURE`` 1 = manual, 3 = auto) and the focus
        (``CAP_PROP_AUTOFOCUS`` 0/1, ``CAP_PROP_FOCUS``) are kept and read back."""
        if prop_id in (cv2.CAP_PROP_FRAME_WIDTH, cv2.CAP_PROP_FRAME_HEIGHT):
            axis = 0 if prop_id == cv2.CAP_PROP_FRAME_WIDTH else 1
            self._asked_size[axis] = int(value)
            asked = tuple(self._asked_size)
            for mode in (V4L2_DEFAULT_SIZE, (self.width, self.height)):
                if asked == mode and mode != self.stream_size:
                    self.stream_size = mode
                    self._set_rate()
            return True
        if prop_id == cv2.CAP_PROP_FPS:
            self._asked_fps = float(value)
            self._set_rate()
            return True
        if prop_id == cv2.CAP_PROP_FOURCC:
            asked = int(value).to_bytes(4, "little").decode("ascii", "replace")
            if asked in self.formats:
                self.fourcc = asked
                self._set_rate()
            return True
        if prop_id in self._controls:
            self._controls[prop_id] = float(value)
            if prop_id == cv2.CAP_PROP_AUTO_EXPOSURE:
                self._restart_stream()  # the frames' timing may change with it
            return True
        return False

    def _set_rate(self) -> None:
        """The rate asked for, as far as the pixel format and size allow; a new format,
        size or rate restarts the stream."""
        width, height = self.stream_size
        limit = YUYV_BYTES_PER_S / (2 * width * height) if self.fourcc == "YUYV" else math.inf
        self.fps = min(self._asked_fps, limit)
        self._restart_stream()

    def stop_frames(self, at_s: float | None = None) -> None:
        """From clock time ``at_s`` (default now) no frame comes: a grab blocks."""
        self._frames_stop_s = self.clock.now() if at_s is None else float(at_s)

    def jump_clock(self, by_s: float) -> None:
        """Every later frame's stamp is off by ``by_s`` (the camera's clock jumped)."""
        self._clock_jump_s = float(by_s)

    def _restart_stream(self) -> None:
        """A new format: the stream stops (its queued buffers are dropped) and starts
        again at the next read, where the exposure settles again."""
        self._streaming = False

    def get(self, prop_id: int) -> float:
        if prop_id == cv2.CAP_PROP_POS_MSEC:  # asked after every frame's grab
            return self._pos_msec
        if prop_id == cv2.CAP_PROP_FPS:  # and the rate, to judge the frame's stamp
            return self.fps
        return {
            cv2.CAP_PROP_FRAME_WIDTH: float(self.stream_size[0]),
            cv2.CAP_PROP_FRAME_HEIGHT: float(self.stream_size[1]),
            cv2.CAP_PROP_FPS: self.fps,
            cv2.CAP_PROP_FOURCC: float(int.from_bytes(self.fourcc.encode("ascii"), "little")),
            **self._controls,
        }.get(prop_id, 0.0)

    def getBackendName(self) -> str:
        return "V4L2"

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
            str(path),
            cv2.VideoWriter_fourcc(*"MJPG"),
            fps,
            (self.width, self.height),
            self.channels == 3,
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
