"""A run's video: the camera's frames written to a file as they arrive.

The file sits beside the run file with the same stem (``RUN.avi``, Motion-JPEG; or
``.mkv`` with Motion-JPEG, ``.mp4`` with MPEG-4 part 2), written by OpenCV's FFmpeg
writer. Each frame's time on the run's clock is stored in the run file
(``/entry/video/time``, ``labrig.storage``), in the same order, so frame i of the video
is the frame measured at time i.

Encoding runs in a thread of its own, fed through a bounded queue: the camera loop only
hands a frame over (a simulated frame is rendered in full here, not in the loop), and
when the encoder falls behind by the whole queue the hand-over waits. That thread never
waits on the clock, so on the simulated rig's virtual clock it cannot move or hold time;
a camera loop waiting for queue room holds time still and costs only wall time.

AVI and Matroska are written front to back with the frames in order, so a killed run's
video opens and plays up to what the writer had passed to the file (FFmpeg's write
buffer, a few hundred kB: well under a second of frames); an MP4 is unreadable until
its index is written at the end, which is why it is not the default.
"""

from __future__ import annotations

import queue
import threading
from pathlib import Path

import numpy as np

FOURCC = {".avi": "MJPG", ".mkv": "MJPG", ".mp4": "mp4v"}
QUEUE_FRAMES = 32
_END = object()


class VideoRecorder:
    """Frames to ``path`` at ``fps`` (the nominal rate written into the file; the true
    times are in the run file). The size is taken from the first frame."""

    def __init__(self, path: str | Path, fps: float, queue_frames: int = QUEUE_FRAMES) -> None:
        self.path = Path(path)
        if self.path.suffix not in FOURCC:
            raise ValueError(f"{self.path}: a video is .avi, .mkv or .mp4")
        self.fps = float(fps)
        self.n_frames = 0  # handed over
        self.n_written = 0
        self.error: OSError | None = None
        self._queue: queue.Queue = queue.Queue(maxsize=queue_frames)
        self._thread: threading.Thread | None = None
        self._writer = None  # a cv2.VideoWriter once the first frame gives the size

    def add(self, image) -> None:
        """Hand one frame over (an array or an array-like that renders on access)."""
        if self.error is not None:
            raise self.error
        if self._thread is None:
            self._thread = threading.Thread(target=self._encode, name="video", daemon=True)
            self._thread.start()
        self._queue.put(image)
        self.n_frames += 1

    def _encode(self) -> None:
        while (item := self._queue.get()) is not _END:
            if self.error is not None:
                continue  # drain: the camera loop learns of the error at its next frame
            try:
                self._write(np.asarray(item))
            except OSError as exc:
                self.error = exc

    def _write(self, image: np.ndarray) -> None:
        import cv2  # only a run with a video needs OpenCV's writer

        if self._writer is None:
            height, width = image.shape[:2]
            self._writer = cv2.VideoWriter(
                str(self.path),
                cv2.VideoWriter_fourcc(*FOURCC[self.path.suffix]),
                self.fps,
                (width, height),
                image.ndim == 3,
            )
            if not self._writer.isOpened():
                raise OSError(f"{self.path}: OpenCV cannot write this video here")
        self._writer.write(image)
        self.n_written += 1

    def close(self) -> int:
        """Write what is queued and close the file; the number of frames written."""
        if self._thread is not None:
            self._queue.put(_END)
            self._thread.join()
            self._thread = None
        if self._writer is not None:
            self._writer.release()
            self._writer = None
        return self.n_written
