"""Two-marker tracker: sub-pixel marker centres in camera frames, identity kept.

Thresholds and connected components only *find* each marker; its centre comes from
intensity-weighted moments of the background-subtracted grey levels in a circular
window around it, which uses the anti-aliased edge pixels a binary mask throws away
(about 0.03 px against 0.1 px for a binary contour centroid on an anti-aliased disc).

Per frame it looks only inside a window around each marker's last position and searches
the whole frame only when a marker is lost, so tracking costs well under a millisecond
per frame while the markers are held; a batch of frames (``track_many``) has the held
markers' windows of all its frames searched and centred in one pass. A marker that is
lost, or two that merged into one blob, give NaN and ``ok=False``: a wrong length is
worse than none.

Pixel coordinates follow OpenCV: the centre of pixel (column i, row j) is at (i, j).
This module knows nothing of cameras, files or clocks (``labrig.drivers.camera``).
"""

from __future__ import annotations

import functools
import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import NamedTuple

import cv2
import numpy as np

from labrig.arrays import nanmedian_rows
from labrig.errors import InputError

# A marker's blob is round: it fills about pi/4 of its bounding box, which is about square.
_MIN_FILL = 0.55
_MAX_ASPECT = 1.6
# How far a held marker may move within one batch of frames and still be measured in it
# (a snap moves it a few px a frame at 30 fps); beyond, the frames go one by one.
_BATCH_MOTION_PX = 8
# Two touching markers make one blob of about twice a marker's area.
_MERGED_AREA = (1.3, 2.8)


@dataclass(frozen=True)
class MarkerFix:
    """The two markers in one frame, in px. NaN and ``ok=False`` unless both were found;
    ``status`` says why not: "lost", "merged" (one blob, or two too close to measure
    apart) or "ambiguous" (more than two look-alike blobs)."""

    x1_px: float
    y1_px: float
    x2_px: float
    y2_px: float
    ok: bool
    status: str

    @property
    def distance_px(self) -> float:
        return math.hypot(self.x2_px - self.x1_px, self.y2_px - self.y1_px)


class _Blob(NamedTuple):
    """A candidate blob (a tuple: a frame makes several, and a frozen dataclass costs
    more to build than its tests)."""

    x: float  # coarse centre (the blob's binary centroid), frame px
    y: float
    area_px: float
    round: bool


def _failed(status: str) -> MarkerFix:
    nan = float("nan")
    return MarkerFix(nan, nan, nan, nan, ok=False, status=status)


class MarkerTracker:
    """Tracks two markers from frame to frame.

    By default the markers are dark round dots on a lighter specimen, found below an
    automatic (Otsu) grey threshold; ``threshold`` fixes the grey level instead, and
    ``hsv_range=((h, s, v), (h, s, v))`` finds coloured markers with ``cv2.inRange``
    (OpenCV hue runs 0-179) and centres them on their saturation. ``max_step_px`` is the
    farthest a marker may move between two frames and still be found near its last
    position.
    """

    def __init__(
        self,
        *,
        threshold: int | None = None,
        hsv_range: tuple[tuple[int, int, int], tuple[int, int, int]] | None = None,
        min_area_px: float = 12.0,
        max_area_px: float = 40_000.0,
        max_step_px: float = 24.0,
        min_contrast: float = 20.0,
    ) -> None:
        if threshold is not None and not 0 < threshold < 255:
            raise InputError(f"marker threshold: a grey level 1-254, got {threshold}")
        if hsv_range is not None:
            lo, hi = (np.asarray(b, dtype=np.uint8) for b in hsv_range)
            if lo.shape != (3,) or hi.shape != (3,):
                raise InputError("marker hsv_range: two (h, s, v) triples, h 0-179, s and v 0-255")
            self._hsv = (lo, hi)
        else:
            self._hsv = None
        if not 0 < min_area_px < max_area_px:
            raise InputError("marker area limits: need 0 < min_area_px < max_area_px")
        self.threshold = threshold
        self.min_area_px = float(min_area_px)
        self.max_area_px = float(max_area_px)
        self.max_step_px = float(max_step_px)
        self.min_contrast = float(min_contrast)
        self.reset()

    def reset(self) -> None:
        """Forget the last positions: the next frame is searched whole."""
        # the last good centres, in marker order: ((x1, y1), (x2, y2))
        self._last: tuple[tuple[float, float], tuple[float, float]] | None = None
        self._area_px: float | None = None  # a marker's blob area in the last good frame
        self.full_searches = 0

    # -- the public step -------------------------------------------------------------------

    def track(self, frame: np.ndarray) -> MarkerFix:
        """Find both markers in a BGR (or grey) frame; keeps their identity between calls."""
        if frame is None or frame.ndim not in (2, 3) or frame.size == 0:
            raise InputError("marker tracking: the frame is empty or not an image")
        if self._hsv is not None and frame.ndim != 3:
            raise InputError("marker tracking: colour markers (hsv_range) need colour frames")
        if self._last is not None:
            fix = self._track_near_last(frame)
            if fix is not None:
                return fix
        self.full_searches += 1
        blobs = self._blobs(frame, 0, 0, frame.shape[1], frame.shape[0])
        return self._accept(frame, blobs, near=None)

    def track_many(self, frames: Sequence[np.ndarray]) -> list[MarkerFix]:
        """``track`` on each of a batch of consecutive frames, in order.

        While both markers are held, their windows are searched in every frame of the
        batch at once (``_track_held``): the windows around the positions before the
        batch, one connected-components pass over all of them, the centres refined by
        one vectorised pass — the same tests and the same centroid as frame by frame,
        for a fraction of the calls. From the first frame where that does not clearly
        find both markers (one lost, merged, ambiguous, moved near its window's edge),
        the batch goes on frame by frame, which decides what the frame shows."""
        frames = list(frames)
        held = self._track_held(frames) if self._batchable(frames) else []
        return held + [self.track(frame) for frame in frames[len(held) :]]

    def _batchable(self, frames: list) -> bool:
        if self._last is None or self._hsv is not None or len(frames) < 2:
            return False
        shape = getattr(frames[0], "shape", None)
        return (
            shape is not None
            and len(shape) in (2, 3)
            and all(getattr(f, "shape", None) == shape for f in frames)
        )

    def _track_held(self, frames: list) -> list[MarkerFix]:
        """The fixes of the longest run of frames, from the first, in which each held
        marker's window shows exactly one marker-like blob; [] when none."""
        h, w = frames[0].shape[:2]
        # a window just larger than a centroid window (``_refine``) by the motion a batch
        # may hold: a quarter of the pixels of a frame-by-frame search window
        radius_px = math.sqrt(self._area_px / math.pi)
        half = math.ceil(radius_px + 7.0) + _BATCH_MOTION_PX
        boxes = []
        for x, y in self._last:
            box = (max(int(x) - half, 0), max(int(y) - half, 0),
                   min(int(x) + half + 1, w), min(int(y) + half + 1, h))  # fmt: skip
            if box[0] >= box[2] or box[1] >= box[3]:
                return []
            boxes.append(box)
        if _overlap(*boxes):
            return []  # close markers: frame by frame tells merged from apart
        n = len(frames)
        if boxes[0][2] - boxes[0][0] == boxes[1][2] - boxes[1][0] and (
            boxes[0][3] - boxes[0][1] == boxes[1][3] - boxes[1][1]
        ):  # both windows in one stack (unless the frame's edge cut one to another size)
            windows = [boxes[0]] * n + [boxes[1]] * n
            lasts = [self._last[0]] * n + [self._last[1]] * n
            found = self._held_in_windows(frames * 2, windows, lasts, half)
            (ok1, ok2), (x1, x2), (y1, y2), (area1, area2) = (v.reshape(2, n) for v in found)
        else:
            (ok1, x1, y1, area1), (ok2, x2, y2, area2) = (
                self._held_in_windows(frames, [box] * n, [last] * n, half)
                for box, last in zip(boxes, self._last, strict=True)
            )
        # too close to measure apart, or in the other order, is for the frame-by-frame
        # tests to judge (as ``_accept`` does, against the fix of the frame before)
        apart_px = np.hypot(x2 - x1, y2 - y1)
        radii_px = np.sqrt(area1 / math.pi) + np.sqrt(area2 / math.pi) + 8.0
        (lx1, ly1), (lx2, ly2) = self._last
        bx1, by1, bx2, by2 = (np.concatenate([[last], now[:-1]]) for last, now in
                              ((lx1, x1), (ly1, y1), (lx2, x2), (ly2, y2)))  # fmt: skip
        straight = np.hypot(x1 - bx1, y1 - by1) + np.hypot(x2 - bx2, y2 - by2)
        swapped = np.hypot(x2 - bx1, y2 - by1) + np.hypot(x1 - bx2, y1 - by2)
        ok = ok1 & ok2 & (apart_px >= radii_px) & ~(swapped < straight)
        n = n if ok.all() else int(np.argmin(ok))
        if n == 0:
            return []
        self._last = ((float(x1[n - 1]), float(y1[n - 1])), (float(x2[n - 1]), float(y2[n - 1])))
        self._area_px = 0.5 * float(area1[n - 1] + area2[n - 1])
        return [
            MarkerFix(*row, ok=True, status="ok")
            for row in np.column_stack([x1[:n], y1[:n], x2[:n], y2[:n]]).tolist()
        ]

    def _held_in_windows(self, frames: list, boxes: list, lasts: list, near: int):
        """Window i (``boxes[i]``, all of one size) of frame i, for every i:
        (found, x_px, y_px, area_px), arrays over them; found where exactly one blob in
        the window is marker-like (``_accept``'s tests), within ``near`` of ``lasts[i]``,
        and its centroid window lies inside the window."""
        x0, y0 = (np.array([box[k] for box in boxes]) for k in (0, 1))
        bw, bh, n = boxes[0][2] - boxes[0][0], boxes[0][3] - boxes[0][1], len(frames)
        last_x, last_y = (np.array([last[k] for last in lasts]) for k in (0, 1))
        stack = _stack_regions(frames, boxes)
        grey = (
            stack
            if stack.ndim == 3
            else cv2.cvtColor(stack.reshape(n * bh, bw, 3), cv2.COLOR_BGR2GRAY).reshape(n, bh, bw)
        )
        # each window's mask, as ``_mask`` makes it, with an empty row below it: one
        # connected-components pass labels every window's blobs apart
        masks = np.zeros((n, bh + 1, bw), dtype=np.uint8)
        if self.threshold is not None:
            masks[:, :bh] = grey <= self.threshold
        else:
            for k in range(n):
                cv2.threshold(grey[k], 0, 1, cv2.THRESH_BINARY_INV | cv2.THRESH_OTSU,
                              dst=masks[k, :bh])  # fmt: skip
            flat = grey.reshape(n, -1)
            masks[flat.max(axis=1).astype(int) - flat.min(axis=1) < self.min_contrast] = 0
        rows = masks.reshape(n * (bh + 1), bw)
        ltype = cv2.CV_16U if rows.size < 2 * 65535 else cv2.CV_32S
        _, _, stats, centroids = cv2.connectedComponentsWithStats(rows, connectivity=8, ltype=ltype)
        sw, sh, area = stats[1:, 2:].T.astype(float)  # label 0 is the background
        frame_of = stats[1:, cv2.CC_STAT_TOP] // (bh + 1)
        cx = x0[frame_of] + centroids[1:, 0]
        cy = y0[frame_of] + centroids[1:, 1] - frame_of * (bh + 1)
        aspect = np.maximum(sw, sh) / np.maximum(np.minimum(sw, sh), 1)
        marker_like = (
            (self.min_area_px <= area) & (area <= self.max_area_px)
            & (area >= _MIN_FILL * sw * sh) & (aspect <= _MAX_ASPECT)
            & (0.4 * self._area_px <= area) & (area <= 2.5 * self._area_px)
            & (np.hypot(cx - last_x[frame_of], cy - last_y[frame_of]) <= near)
        )  # fmt: skip
        found = np.bincount(frame_of[marker_like], minlength=n) == 1
        if not found.any():
            nowhere = np.zeros(n)
            return found, nowhere, nowhere, nowhere
        blob = np.zeros(n, dtype=int)
        blob[frame_of[marker_like]] = np.flatnonzero(marker_like)
        x, y, a = cx[blob], cy[blob], area[blob]
        # the sub-pixel centre (``_refine``), all frames at once: moments of the
        # darkness less the ring's median, in a window around the rounded coarse centre
        r_in = np.sqrt(a / math.pi) + 4.0
        reach = math.ceil(float(r_in.max()) + 3.0)
        side = 2 * reach + 1
        offsets = np.arange(-reach, reach + 1, dtype=float)
        r2 = offsets[None, :] ** 2 + offsets[:, None] ** 2
        left_px = np.rint(x).astype(int) - reach - x0
        top_px = np.rint(y).astype(int) - reach - y0
        found &= (left_px >= 0) & (top_px >= 0) & (left_px + side <= bw) & (top_px + side <= bh)
        if not found.any():
            return found, x, y, a
        left_px, top_px = np.where(found, left_px, 0), np.where(found, top_px, 0)
        patches = np.lib.stride_tricks.sliding_window_view(grey, (side, side), axis=(1, 2))
        signal = 255.0 - patches[np.arange(n), top_px, left_px].astype(np.float32)
        inside = r2[None] <= (r_in * r_in)[:, None, None]
        ring = ~inside & (r2[None] <= ((r_in + 3.0) ** 2)[:, None, None])
        # the median of each ring (its pixels kept, the rest NaN)
        background = nanmedian_rows(np.where(ring, signal, np.nan).reshape(n, -1))
        weights = (signal - background.astype(np.float32)[:, None, None]) * inside
        weights = weights.astype(np.float64)
        m00 = weights.sum(axis=(1, 2))
        found &= m00 > 0
        m00 = np.where(found, m00, 1.0)
        x_px = x0 + left_px + (weights.sum(axis=1) @ np.arange(side, dtype=float)) / m00
        y_px = y0 + top_px + (weights.sum(axis=2) @ np.arange(side, dtype=float)) / m00
        return found, x_px, y_px, a

    # -- searching ---------------------------------------------------------------------------

    def _window_half_px(self) -> int:
        radius = math.sqrt((self._area_px or 100.0) / math.pi)
        return math.ceil(2.0 * radius + self.max_step_px + 4)

    def _track_near_last(self, frame: np.ndarray) -> MarkerFix | None:
        """Search windows around the last positions; None when that is not enough."""
        h, w = frame.shape[:2]
        half = self._window_half_px()
        boxes = []
        for x, y in self._last:
            x0, y0 = max(int(x) - half, 0), max(int(y) - half, 0)
            x1, y1 = min(int(x) + half + 1, w), min(int(y) + half + 1, h)
            if x0 < x1 and y0 < y1:
                boxes.append([x0, y0, x1, y1])
        if len(boxes) == 2 and _overlap(*boxes):
            (ax0, ay0, ax1, ay1), (bx0, by0, bx1, by1) = boxes
            boxes = [[min(ax0, bx0), min(ay0, by0), max(ax1, bx1), max(ay1, by1)]]
        blobs = [b for box in boxes for b in self._blobs(frame, *box)]
        fix = self._accept(frame, blobs, near=half)
        # A merged pair is seen best near the last positions; a lost marker may have moved
        # anywhere, so only that sends the tracker to the whole frame.
        return None if fix.status == "lost" else fix

    def _blobs(self, frame: np.ndarray, x0: int, y0: int, x1: int, y1: int) -> list[_Blob]:
        """Candidate blobs inside a box, in frame coordinates."""
        mask = self._mask(frame[y0:y1, x0:x1])
        # 16-bit labels are 3x faster (OpenCV 4.x/5.x); a region of fewer than 2 * 65535
        # pixels cannot hold more components than they count
        ltype = cv2.CV_16U if mask.size < 2 * 65535 else cv2.CV_32S
        _, _, stats, centroids = cv2.connectedComponentsWithStats(mask, connectivity=8, ltype=ltype)
        # plain Python on the components' rows (a window holds a few, a noisy one
        # dozens): cheaper than numpy's calls on arrays this small
        blobs = []
        for (_, _, bw, bh, area), (cx, cy) in zip(
            stats.tolist()[1:], centroids.tolist()[1:], strict=True
        ):  # label 0 is the background
            if not self.min_area_px <= area <= self.max_area_px:
                continue
            aspect = max(bw, bh) / max(min(bw, bh), 1)
            is_round = area >= _MIN_FILL * bw * bh and aspect <= _MAX_ASPECT
            blobs.append(_Blob(x0 + cx, y0 + cy, float(area), is_round))
        return blobs

    def _mask(self, region: np.ndarray) -> np.ndarray:
        if self._hsv is not None:
            return cv2.inRange(cv2.cvtColor(region, cv2.COLOR_BGR2HSV), *self._hsv)
        grey = _grey(region)
        if self.threshold is not None:
            return cv2.threshold(grey, self.threshold, 255, cv2.THRESH_BINARY_INV)[1]
        _, mask = cv2.threshold(grey, 0, 255, cv2.THRESH_BINARY_INV | cv2.THRESH_OTSU)
        # Otsu always splits, even a region of plain specimen: demand real contrast.
        darkest, brightest, _, _ = cv2.minMaxLoc(grey)
        if brightest - darkest < self.min_contrast:
            mask[:] = 0
        return mask

    # -- choosing and measuring -----------------------------------------------------------------

    def _accept(self, frame: np.ndarray, blobs: list[_Blob], near: int | None) -> MarkerFix:
        """Pick the two markers among the candidates, refine them, keep their identity."""
        blobs = _unique(blobs)
        markers = [b for b in blobs if b.round]
        if self._area_px is not None:
            markers = [
                b for b in markers if 0.4 * self._area_px <= b.area_px <= 2.5 * self._area_px
            ]
        if near is not None:
            markers = self._nearest_to_last(markers, near)
        if len(markers) != 2:
            if len(markers) > 2:
                markers.sort(key=lambda b: b.area_px, reverse=True)
                if markers[2].area_px > 0.5 * markers[1].area_px:
                    return _failed("ambiguous")
                markers = markers[:2]
            else:
                return _failed("merged" if self._has_merged(blobs) else "lost")
        first, second = markers
        apart_px = math.hypot(first.x - second.x, first.y - second.y)
        if apart_px < _window_radius_px(first) + _window_radius_px(second):
            # Each centre's window would hold part of the other marker and be pulled
            # towards it: too close to measure apart is as good as merged.
            return _failed("merged")
        (x1, y1), (x2, y2) = (self._refine(frame, b) for b in markers)
        if not all(map(math.isfinite, (x1, y1, x2, y2))):
            return _failed("lost")
        if self._in_swapped_order(x1, y1, x2, y2):
            x1, y1, x2, y2 = x2, y2, x1, y1
        self._last = ((x1, y1), (x2, y2))
        self._area_px = 0.5 * (markers[0].area_px + markers[1].area_px)
        return MarkerFix(x1, y1, x2, y2, ok=True, status="ok")

    def _nearest_to_last(self, markers: list[_Blob], near: int) -> list[_Blob]:
        """For each last position the nearest candidate within ``near`` px, or nothing."""
        chosen = []
        for x, y in self._last:
            if not markers:
                break
            best = min(markers, key=lambda b: math.hypot(b.x - x, b.y - y))
            if math.hypot(best.x - x, best.y - y) <= near and best not in chosen:
                chosen.append(best)
        return chosen

    def _has_merged(self, blobs: list[_Blob]) -> bool:
        if self._area_px is None:
            return False
        lo, hi = _MERGED_AREA
        return any(lo * self._area_px <= b.area_px <= hi * self._area_px for b in blobs)

    def _in_swapped_order(self, x1: float, y1: float, x2: float, y2: float) -> bool:
        """Whether the two centres are the markers in the other order: by nearest
        neighbour to the last positions; the first time, left to right (then top to
        bottom)."""
        if self._last is None:
            return (x2, y2) < (x1, y1)
        (lx1, ly1), (lx2, ly2) = self._last
        straight = math.hypot(x1 - lx1, y1 - ly1) + math.hypot(x2 - lx2, y2 - ly2)
        swapped = math.hypot(x2 - lx1, y2 - ly1) + math.hypot(x1 - lx2, y1 - ly2)
        return swapped < straight

    def _refine(self, frame: np.ndarray, blob: _Blob) -> tuple[float, float]:
        """Sub-pixel centre: intensity-weighted moments in a circular window.

        The window is centred on the coarse centre, so zero-mean noise and any error in the
        background level pull the result only towards that centre, by a tiny fraction;
        the background is the median of a ring just outside the window.
        """
        h, w = frame.shape[:2]
        r_in = _window_radius_px(blob)
        r_out = r_in + 3.0
        half = math.ceil(r_out)
        cx, cy = round(blob.x), round(blob.y)
        x0, y0, x1, y1 = cx - half, cy - half, cx + half + 1, cy + half + 1
        if x0 < 0 or y0 < 0 or x1 > w or y1 > h:
            return (float("nan"), float("nan"))  # cut by the frame edge: not measurable
        signal = self._signal(frame[y0:y1, x0:x1])  # a new array: changed in place
        inside, ring = _window_masks(half, r_in)
        background = _median(signal.ravel().take(ring))
        signal -= np.float32(background)
        signal *= inside  # the weights: 0 outside the window
        m = cv2.moments(signal)
        if m["m00"] <= 0:
            return (float("nan"), float("nan"))
        return (x0 + m["m10"] / m["m00"], y0 + m["m01"] / m["m00"])

    def _signal(self, patch: np.ndarray) -> np.ndarray:
        """What makes a marker stand out, as float: darkness, or saturation for colour."""
        if self._hsv is not None:
            return cv2.cvtColor(patch, cv2.COLOR_BGR2HSV)[:, :, 1].astype(np.float32)
        return 255.0 - _grey(patch).astype(np.float32)


@functools.lru_cache(maxsize=64)
def _window_masks(half: int, r_in: float) -> tuple[np.ndarray, np.ndarray]:
    """The centroid window (1 within ``r_in`` of the centre, else 0, as float32) and the
    flat indices of the background ring (from there to ``r_in`` + 3) of a
    (2 half + 1)^2 patch; a held marker's blob keeps a few areas, so these are made
    once each."""
    offsets = np.arange(-half, half + 1)
    r2 = offsets[None, :] ** 2 + offsets[:, None] ** 2
    inside = r2 <= r_in * r_in
    r_out = r_in + 3.0
    return inside.astype(np.float32), np.flatnonzero(~inside & (r2 <= r_out * r_out))


def _stack_regions(frames: list, boxes: list) -> np.ndarray:
    """Box i (x0, y0, x1, y1, all of one size) of frame i, stacked: (n, h, w[, 3]). A
    frame type that renders only what is read (``labrig.sim.camera_frame.SimFrame``) renders
    them together."""
    stack_regions = getattr(type(frames[0]), "stack_regions", None)
    stack = stack_regions(frames, boxes) if stack_regions is not None else None
    if stack is None:
        stack = np.stack(
            [f[y0:y1, x0:x1] for f, (x0, y0, x1, y1) in zip(frames, boxes, strict=True)]
        )
    return stack


def _median(values: np.ndarray) -> float:
    """``np.median`` of a small 1-d array (reordered in place), without its generic
    machinery's cost."""
    n = values.size
    k = n // 2
    if n == 0:
        return float("nan")
    if n % 2:
        values.partition(k)
        return float(values[k])
    values.partition([k - 1, k])
    return 0.5 * (float(values[k - 1]) + float(values[k]))


def _window_radius_px(blob: _Blob) -> float:
    """The centroid window: the blob's radius plus room for its blurred edge."""
    return math.sqrt(blob.area_px / math.pi) + 4.0


def _grey(image: np.ndarray) -> np.ndarray:
    return image if image.ndim == 2 else cv2.cvtColor(image, cv2.COLOR_BGR2GRAY)


def _overlap(a: list[int], b: list[int]) -> bool:
    return a[0] < b[2] and b[0] < a[2] and a[1] < b[3] and b[1] < a[3]


def _unique(blobs: list[_Blob]) -> list[_Blob]:
    """Drop a blob seen twice (two search windows over the same marker)."""
    kept: list[_Blob] = []
    for b in blobs:
        if all(math.hypot(b.x - k.x, b.y - k.y) > 1.0 for k in kept):
            kept.append(b)
    return kept


def mm_per_px_from_reference(fix: MarkerFix, reference_distance_mm: float) -> float:
    """The scale from a frame whose markers are a known distance apart."""
    if not reference_distance_mm > 0:
        raise InputError(f"reference distance: must be > 0 mm, got {reference_distance_mm}")
    if not fix.ok or not fix.distance_px > 0:
        raise InputError(
            f"reference frame: both markers must be visible and apart (they were {fix.status})"
        )
    return reference_distance_mm / fix.distance_px
