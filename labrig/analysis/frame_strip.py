"""Frame strips from a run's video: the paper's snapshot figures.

``labrig frames RUN.h5 --at-transitions`` shows, for each transition the analysis
measured, the frame just before it starts and just after it ends (the volumes where its
steepness bump begins and ends); ``--at-volumes`` shows the frames where a repetition's
inflation first reaches chosen volumes. Each tile is the video frame scaled to
``TILE_WIDTH_PX``, with the tracked markers ringed, a dimension line above them with
the measured length, and under it the repetition, time, volume and pressure.

The frames come from the video beside the run file (``/entry/video``: its file name
and each frame's time on the run's clock, in the video's order); the markers, length,
volume and pressure come from the run file's series at the frame's time.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from labrig.analysis.runfile import RunRecord
from labrig.errors import InputError
from labrig.recording.run_reader import open_run

TILE_WIDTH_PX = 640
CAPTION_PX = 52
RING_PX = 10  # the ring's radius beyond the marker, in tile px
GREEN, YELLOW, WHITE = (60, 220, 60), (0, 220, 255), (255, 255, 255)


@dataclass(frozen=True)
class Tile:
    """One frame of the strip and what is written under it."""

    index: int  # frame number in the video
    t_s: float
    repetition: int
    label: str


@dataclass(frozen=True)
class VideoIndex:
    path: Path
    t_s: np.ndarray
    repetition: np.ndarray

    def frame_at(self, t_s: float) -> int:
        """The frame nearest in time to ``t_s``."""
        return int(np.argmin(np.abs(self.t_s - t_s)))

    def last_before(self, t_s: float) -> int:
        return max(0, int(np.searchsorted(self.t_s, t_s, side="right")) - 1)

    def first_after(self, t_s: float) -> int:
        return min(len(self.t_s) - 1, int(np.searchsorted(self.t_s, t_s, side="left")))


def video_index(run_path: Path) -> VideoIndex:
    """The run's video file and frame times; InputError if it has none."""
    with open_run(run_path) as run:
        if "entry/video" not in run:
            raise InputError(
                f"{run_path}: no video was recorded (set acquisition: {{video: true}} in the "
                "protocol)"
            )
        group = run["entry/video"]
        name = group.attrs["file"]
        t_s, repetition = group["time"][:], group["repetition"][:]
    path = run_path.parent / (name.decode() if isinstance(name, bytes) else str(name))
    if not path.is_file():
        raise InputError(f"{run_path}: its video {path} is missing (it is kept beside the run)")
    if len(t_s) == 0:
        raise InputError(f"{run_path}: the video has no frames")
    return VideoIndex(path, t_s, repetition)


def _time_at_volume(rep, v_ml: float, near_s: float, direction: int) -> float:
    """When the supplied volume passed ``v_ml`` in the motion around ``near_s``."""
    t, v = rep.pump.time_s, rep.pump.fields["value"]
    inside = (t >= near_s - 60.0) & (t <= near_s + 60.0)
    t, v = t[inside], v[inside] * direction
    if len(t) < 2:
        return near_s
    ahead = np.maximum.accumulate(v)  # monotone in the motion's direction
    return float(np.interp(direction * v_ml, ahead, t))


def transition_tiles(record: RunRecord, result, video: VideoIndex) -> list[Tile]:
    """Before and after each transition measured in the repetitions with video."""
    reps = {rep.index: rep for rep in record.repetitions}
    tiles = []
    for rep_result in result.repetitions:
        for k, tr in enumerate(rep_result.transitions, 1):
            rep = reps[rep_result.index]
            if not np.any(video.repetition == rep.index):
                continue
            t_from = _time_at_volume(rep, tr.v_start_ml, tr.t_s, tr.direction)
            t_to = _time_at_volume(rep, tr.v_end_ml, tr.t_s, tr.direction)
            phase = "inflation" if tr.direction > 0 else "deflation"
            name = f"transition {k} of rep {rep.index} ({phase}, at {tr.v_ml:.2f} mL)"
            for when, index in (
                ("before", video.last_before(min(t_from, tr.t_s))),
                ("after", video.first_after(max(t_to, tr.t_s))),
            ):
                tiles.append(Tile(index, float(video.t_s[index]), rep.index, f"{when} {name}"))
    if not tiles:
        raise InputError(f"{record.path}: no transition was measured during the video")
    return tiles


def volume_tiles(
    record: RunRecord, video: VideoIndex, volumes_ml: list[float], repetition: int | None
) -> list[Tile]:
    """The frames where a repetition's inflation first reaches each volume."""
    with_video = sorted(set(int(r) for r in video.repetition))
    index = repetition if repetition is not None else with_video[-1]
    if index not in with_video:
        raise InputError(f"--repetition {index}: no video frames in it (video covers {with_video})")
    rep = next(r for r in record.repetitions if r.index == index)
    t, v = rep.pump.time_s, rep.pump.fields["value"]
    tiles = []
    for volume in volumes_ml:
        reached = np.nonzero(v >= volume)[0]
        if len(reached) == 0:
            raise InputError(
                f"--at-volumes {volume:g}: repetition {index} reached only {np.max(v):.2f} mL"
            )
        k = reached[0]
        t_at = t[k] if k == 0 else float(np.interp(volume, v[k - 1 : k + 1], t[k - 1 : k + 1]))
        frame = video.frame_at(t_at)
        tiles.append(Tile(frame, float(video.t_s[frame]), index, f"rep {index} at {volume:g} mL"))
    return tiles


def read_frames(video: VideoIndex, indices: list[int]) -> dict[int, np.ndarray]:
    """Frames of the video by number: sought directly, read through when seeking fails
    (a killed run's file has no index)."""
    import cv2

    capture = cv2.VideoCapture(str(video.path))
    if not capture.isOpened():
        raise InputError(f"{video.path}: OpenCV cannot read this video")
    frames: dict[int, np.ndarray] = {}
    try:
        position = 0
        for index in sorted(set(indices)):
            if index != position:
                capture.set(cv2.CAP_PROP_POS_FRAMES, index)
                position = int(capture.get(cv2.CAP_PROP_POS_FRAMES))
                if position != index:  # no index to seek with: read through from the start
                    capture.set(cv2.CAP_PROP_POS_FRAMES, 0)
                    position = 0
                    while position < index and capture.grab():
                        position += 1
            ok, image = capture.read()
            if not ok:
                raise InputError(
                    f"{video.path}: frame {index} cannot be read (the file holds fewer frames "
                    "than the run file lists: a killed run?)"
                )
            frames[index] = image
            position = index + 1
    finally:
        capture.release()
    return frames


def _values_at(rep, t_s: float) -> dict[str, float]:
    """The length log's row nearest ``t_s``, and the volume and pressure then."""
    out = {"v_ml": float(np.interp(t_s, rep.pump.time_s, rep.pump.fields["value"]))}
    p_t, p = rep.pressure.time_s, rep.pressure.fields["value"]
    near = (p_t >= t_s - 0.025) & (p_t <= t_s + 0.025)
    out["p_kpa"] = float(np.mean(p[near])) if np.any(near) else float("nan")
    if rep.length is not None and len(rep.length):
        k = int(np.argmin(np.abs(rep.length.time_s - t_s)))
        for name in ("value", "x1", "y1", "x2", "y2"):
            out[name] = float(rep.length.fields[name][k])
    return out


def render_tile(image: np.ndarray, tile: Tile, values: dict[str, float]) -> np.ndarray:
    """The frame scaled to the tile width, annotated, with its caption band under it."""
    import cv2

    scale = TILE_WIDTH_PX / image.shape[1]
    height = round(image.shape[0] * scale)
    frame = cv2.resize(image, (TILE_WIDTH_PX, height), interpolation=cv2.INTER_AREA)
    if frame.ndim == 2:
        frame = cv2.cvtColor(frame, cv2.COLOR_GRAY2BGR)
    marks = [values.get(k, float("nan")) for k in ("x1", "y1", "x2", "y2")]
    if all(np.isfinite(marks)):
        (x1, y1), (x2, y2) = ((m * scale for m in marks[i : i + 2]) for i in (0, 2))
        for x, y in ((x1, y1), (x2, y2)):
            cv2.circle(frame, (round(x), round(y)), RING_PX, GREEN, 1, cv2.LINE_AA)
        lift = 3 * RING_PX
        ends = [(round(x1), round(y1 - lift)), (round(x2), round(y2 - lift))]
        cv2.line(frame, *ends, YELLOW, 1, cv2.LINE_AA)
        for x, y in ends:
            cv2.line(frame, (x, y - 4), (x, y + 4), YELLOW, 1, cv2.LINE_AA)
        text = f"l = {values['value']:.2f} mm"
        mid = (round(0.5 * (x1 + x2)) - 50, round(0.5 * (y1 + y2) - lift - 8))
        cv2.putText(frame, text, mid, cv2.FONT_HERSHEY_SIMPLEX, 0.5, YELLOW, 1, cv2.LINE_AA)
    caption = np.zeros((CAPTION_PX, TILE_WIDTH_PX, 3), dtype=np.uint8)
    lines = [
        tile.label,
        f"t = {tile.t_s:.2f} s   V = {values['v_ml']:.2f} mL   p = {values['p_kpa']:.2f} kPa",
    ]
    for row, line in enumerate(lines):
        cv2.putText(caption, line, (8, 20 + 22 * row), cv2.FONT_HERSHEY_SIMPLEX, 0.5, WHITE, 1,
                    cv2.LINE_AA)  # fmt: skip
    return np.vstack([frame, caption])


def compose(tiles: list[np.ndarray], columns: int) -> np.ndarray:
    """Tiles in rows of ``columns``, left to right, a black gap after an unfilled row."""
    height, width = tiles[0].shape[:2]
    rows = -(-len(tiles) // columns)
    strip = np.zeros((rows * height, columns * width, 3), dtype=np.uint8)
    for k, tile in enumerate(tiles):
        r, c = divmod(k, columns)
        strip[r * height : (r + 1) * height, c * width : (c + 1) * width] = tile
    return strip


def write_strip(
    record: RunRecord, video: VideoIndex, tiles: list[Tile], columns: int, out: Path
) -> np.ndarray:
    """Render the tiles and write the strip image to ``out``; the strip's pixels."""
    import cv2

    frames = read_frames(video, [t.index for t in tiles])
    reps = {rep.index: rep for rep in record.repetitions}
    images = [render_tile(frames[t.index], t, _values_at(reps[t.repetition], t.t_s)) for t in tiles]
    strip = compose(images, columns)
    if not cv2.imwrite(str(out), strip):
        raise InputError(f"-o {out}: cannot write an image there (PNG: give a .png name)")
    return strip
