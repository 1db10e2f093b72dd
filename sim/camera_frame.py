"""A simulated camera's frame that renders only the pixels that are read.

A tracker reads two small windows per frame, so a frame that draws just what is sliced
out of it (bit for bit the full frame's pixels) costs a few tenths of a millisecond
instead of a full render. The drawing itself is the camera's (``labrig.sim.camera``).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING

import cv2
import numpy as np

if TYPE_CHECKING:
    from .camera import SimCamera
    from .camera_scene import SceneRenderer


class SimFrame:
    """A frame of ``SimCamera`` that renders only the pixels that are read.

    It answers ``shape``, ``ndim``, ``size`` and ``dtype`` like the ndarray it stands
    for; slicing it (``frame[y0:y1, x0:x1]``) renders just that region, and
    ``np.asarray(frame)`` the whole frame. The tracker reads two small windows per frame,
    so a frame it tracks costs a few tenths of a millisecond instead of a full render;
    the region's pixels are those of the full frame, bit for bit.
    """

    dtype = np.dtype(np.uint8)

    def __init__(self, camera: SimCamera, *, t_s, gain, hidden, noise) -> None:
        self.camera = camera
        self.t_s = t_s
        self.gain = gain
        self._centres = None
        self.hidden = hidden
        self.noise = noise
        self._palette = None
        self._layout = None
        self._resize((camera.width, camera.height))
        self._resized_to: tuple[int, int] | None = None
        self._full: np.ndarray | None = None
        self._regions: list[tuple[int, int, int, int, np.ndarray]] = []  # last rendered

    def resized(self, size: tuple[int, int]) -> SimFrame:
        """This frame as the camera's scaler delivers it at another streaming size."""
        self._resized_to = size
        self._resize(size)
        return self

    def _resize(self, size: tuple[int, int]) -> None:
        channels = self.camera.channels
        self.shape = (size[1], size[0], channels)[: 2 if channels == 1 else 3]
        self.ndim = len(self.shape)
        self.size = size[0] * size[1] * channels

    @property
    def centres(self) -> np.ndarray:
        """Where the markers are, asked of the length source when first rendered: a
        frame measured a little after it was taken (a run measures its frames in
        batches) reads the simulated specimen's recorded past instead of making it take
        a step to the frame's time."""
        if self._centres is None:
            self._centres = self.camera.marker_centres_px(self.t_s)
        return self._centres

    def palette(self):
        """The frame's colours under its light (``SimCamera._palette``), made once."""
        if self._palette is None:
            self._palette = self.camera._palette(self.gain)
        return self._palette

    def layout(self) -> tuple[tuple, list]:
        """Where the band and the dots are (``SimCamera.layout``), worked out once."""
        if self._layout is None:
            self._layout = self.camera.layout(self.centres, self.hidden)
        return self._layout

    @property
    def scene(self) -> tuple:
        """The frame as a few numbers (time, marker centres, light, hidden markers, the
        noise's pick, the streaming size): all ``SimCamera.scene_frame`` needs."""
        centres = tuple(self.centres.ravel().tolist())
        return (self.t_s, centres, self.gain, tuple(sorted(self.hidden)), self.noise,
                self._resized_to)  # fmt: skip

    def recipe(self) -> tuple[SceneRenderer, tuple]:
        """(renderer, scene): how another process draws this frame itself instead of
        being handed its pixels (the run's video encoder, ``labrig.recording.video``; the marker
        tracker's process, ``labrig.drivers.tracker_process``)."""
        return self.camera.renderer(), self.scene

    def __getitem__(self, key):
        h, w = self.shape[:2]
        if self._resized_to is None and isinstance(key, tuple) and len(key) >= 2:
            rows, cols = key[0], key[1]
            if isinstance(rows, slice) and isinstance(cols, slice):
                y0, y1, dy = rows.indices(h)
                x0, x1, dx = cols.indices(w)
                if dy == dx == 1:
                    region = self._region(x0, y0, max(x1, x0), max(y1, y0))
                    return region if len(key) == 2 else region[(slice(None), slice(None), *key[2:])]
        return np.asarray(self)[key]

    @staticmethod
    def stack_regions(frames: Sequence, boxes: Sequence[tuple]) -> np.ndarray | None:
        """Box i (x0, y0, x1, y1: [y0:y1, x0:x1], all of one size) of frame i, stacked
        (what a tracker reads from a batch of frames), rendered all at once; None unless
        they are one camera's frames at its sensor size."""
        camera = frames[0].camera
        if all(
            isinstance(f, SimFrame) and f.camera is camera and f._resized_to is None for f in frames
        ):
            return camera.render_stack(frames, boxes)
        return None

    def _region(self, x0: int, y0: int, x1: int, y1: int) -> np.ndarray:
        """The pixels of a box: cut from a box rendered before that holds it (the
        tracker's centroid windows lie inside its search windows), else rendered."""
        for bx0, by0, bx1, by1, pixels in self._regions:
            if bx0 <= x0 and by0 <= y0 and x1 <= bx1 and y1 <= by1:
                return pixels[y0 - by0 : y1 - by0, x0 - bx0 : x1 - bx0].copy()
        pixels = self.camera._render_box(self, x0, y0, x1, y1)
        self._regions = [*self._regions[-3:], (x0, y0, x1, y1, pixels)]
        return pixels.copy()

    def __array__(self, dtype=None, copy=None) -> np.ndarray:
        if self._full is None:
            camera = self.camera
            full = camera._render_box(self, 0, 0, camera.width, camera.height)
            if self._resized_to is not None:
                full = cv2.resize(full, self._resized_to, interpolation=cv2.INTER_AREA)
            self._full = full
        return self._full if dtype is None else self._full.astype(dtype)
