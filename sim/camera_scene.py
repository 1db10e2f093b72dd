"""Drawing a simulated camera's frames: ``SceneRenderer`` redraws them from their scenes
in another process (the video encoder's, the marker tracker's), and the pixel
primitives the camera draws with (the blur as matrices, the dots' blend, single-precision
rounding) are here so that every process draws the same pixels."""

from __future__ import annotations

import functools
import struct
from collections.abc import Sequence
from typing import TYPE_CHECKING

import cv2
import numpy as np

if TYPE_CHECKING:
    from .camera import SimCamera
    from .camera_frame import SimFrame


class SceneRenderer:
    """Draws a ``SimCamera``'s frames from their scenes, wherever it is unpickled: the
    camera is rebuilt from its settings (the seed gives the same noise) on first use."""

    def __init__(self, camera_class: type[SimCamera], spec: dict) -> None:
        self.camera_class = camera_class
        self.spec = spec
        self._camera: SimCamera | None = None

    def __getstate__(self) -> dict:
        return {"camera_class": self.camera_class, "spec": self.spec}

    def __setstate__(self, state: dict) -> None:
        self.camera_class, self.spec, self._camera = state["camera_class"], state["spec"], None

    @property
    def camera(self) -> SimCamera:
        if self._camera is None:
            self._camera = self.camera_class(None, None, **self.spec)  # draws only: no clock
        return self._camera

    def __call__(self, scene: tuple) -> np.ndarray:
        return np.asarray(self.frame(scene))

    def frame(self, scene: tuple) -> SimFrame:
        """The scene's frame, rendered where it is read (a video's encoder reads only
        the rows that ``row_keys`` does not know)."""
        return self.camera.scene_frame(scene)

    def row_keys(self, frame: SimFrame, row_px: int) -> list[tuple | None] | None:
        """Which bands of rows of the frame repeat (``SimCamera.row_keys``)."""
        return self.camera.row_keys(frame, row_px)

    def render_rows(
        self, frames: Sequence[SimFrame], spans: Sequence[tuple[int, int, int]]
    ) -> list[np.ndarray]:
        """For each span (i, y0, y1), the pixel rows [y0, y1) of ``frames[i]``, full
        width: spans of one height rendered as one stack (``SimCamera.render_stack``)."""
        camera = self.camera
        out: list[np.ndarray | None] = [None] * len(spans)
        by_height: dict[int, list[int]] = {}
        for j, (_, y0, y1) in enumerate(spans):
            by_height.setdefault(y1 - y0, []).append(j)
        for js in by_height.values():
            stack = camera.render_stack(
                [frames[spans[j][0]] for j in js],
                [(0, spans[j][1], camera.width, spans[j][2]) for j in js],
            )
            for j, pixels in zip(js, stack, strict=True):
                out[j] = pixels
        return out


@functools.lru_cache(maxsize=8)
def blur_matrix(size: int, sigma_px: float) -> np.ndarray:
    """The Gaussian blur of a line of ``size`` pixels as a matrix: OpenCV's kernel for
    ``sigma_px`` (as ``cv2.GaussianBlur`` takes it for float images) with its reflecting
    border. A stack of dots is blurred by two matrix products, each dot alone as in any
    stack."""
    taps = round(sigma_px * 8 + 1) | 1
    kernel = cv2.getGaussianKernel(taps, sigma_px, cv2.CV_64F).ravel()
    matrix = np.zeros((size, size))
    for i in range(size):
        for t, weight in enumerate(kernel):
            j = i + t - taps // 2
            while not 0 <= j < size:  # reflected about the end pixels, not repeating them
                j = 0 if size == 1 else -j if j < 0 else 2 * (size - 1) - j
            matrix[i, j] += weight
    return matrix


def blend(pixels: np.ndarray, coverage: np.ndarray, marker: np.ndarray) -> np.ndarray:
    """Pixels under a dot: a blend of their level and the marker's by the coverage, in
    single precision, + 0.5 so that truncating to uint8 rounds (both are in 0-255)."""
    blend = pixels.astype(np.float32)
    blend *= 1 - coverage
    blend += marker * coverage
    blend += 0.5
    return blend


def to_float32(value: float) -> float:
    """``value`` rounded to the nearest single-precision float (ties to even)."""
    return _FLOAT32.unpack(_FLOAT32.pack(value))[0]


_FLOAT32 = struct.Struct("f")


def grey_level(bgr: tuple[int, int, int]) -> float:
    """A colour's grey level as ``cv2.cvtColor(..., COLOR_BGR2GRAY)`` weighs it."""
    b, g, r = bgr
    return 0.114 * b + 0.587 * g + 0.299 * r


def fill(image: np.ndarray, x0: int, y0: int, x1: int, y1: int, colour: tuple) -> None:
    """Fill [x0, x1) x [y0, y1) of one image with one colour (cv2 does it ~30x faster
    than numpy)."""
    cv2.rectangle(image, (x0, y0), (x1 - 1, y1 - 1), colour, thickness=cv2.FILLED)
