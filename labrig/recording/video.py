"""A run's video: the camera's frames written to a file as they arrive.

The file sits beside the run file with the same stem (``RUN.avi``, Motion-JPEG; or
``.mkv`` with Motion-JPEG, ``.mp4`` with MPEG-4 part 2). Motion-JPEG frames are encoded by
OpenCV (libjpeg-turbo) and written by FFmpeg's libavformat through PyAV (``_Writer``).
Each frame's time on the run's clock is stored in the run file (``/entry/video/time``,
``labrig.recording.run_writer``), in the same order, so frame i of the video is the frame
measured at time i.

Encoding runs in a process of its own (``python -c 'labrig.recording.video._serve()'``), fed
through a pipe: a batch of frames costs the camera loop one pickled write, and the
encoding runs on another core instead of taking the run's interpreter lock. Frames that
can describe themselves (``recipe()``: a simulated frame, a few numbers) are sent
as those descriptions, a batch at a time, and drawn in the encoder process: only the
rows of MCUs that were not seen before are drawn and encoded, the others copied
(``labrig.recording.jpeg_rows``: a third of the encoder's CPU of drawing and encoding
each frame whole). Any
other frame (a real camera's) is sent as its pixels and encoded whole. When the encoder
falls behind by the pipe's buffer the write waits: on the simulated rig's virtual clock
the camera loop then holds time still and costs only wall time; the encoder process
never waits on the clock, so it can neither move nor hold time.

AVI and Matroska are written front to back with the frames in order, so a killed run's
video opens and plays up to what the writer had passed to the file. A run killed outright
(SIGKILL) closes the encoder's pipe: the encoder writes every frame it was sent and
closes the file. An MP4 is unreadable until its index is written at the end, which is
why it is not the default.
"""

from __future__ import annotations

import contextlib
import json
import pickle
import signal
import subprocess
import sys
from fractions import Fraction
from pathlib import Path

import numpy as np

FOURCC = {".avi": "MJPG", ".mkv": "MJPG", ".mp4": "mp4v"}
_CONTAINERS = {".avi": "avi", ".mkv": "matroska", ".mp4": "mp4"}
# Motion-JPEG quality (OpenCV's scale, 0-100): as close to the frame as FFmpeg's own
# MJPEG encoder at its default (1.56 grey levels mean error on the simulated camera's
# noisy frames, against 1.57), 8.5 kB a 640x360 grey frame (q90: 24 kB)
JPEG_QUALITY = 75
# MPEG-4's bit rate: a bit a pixel a frame (7 Mbit/s at 640x360 and 30 fps), at least this
MPEG4_MIN_BIT_RATE = 2_000_000
# the pipe's buffer: a batch of frames' descriptions (~80 bytes a frame) is written
# and flushed as one; pixels go through at once
PIPE_BUFFER_BYTES = 8192
_ENCODER = "from labrig.recording.video import _serve; _serve()"


class VideoRecorder:
    """Frames to ``path`` at ``fps`` (the nominal rate written into the file; the true
    times are in the run file). The size is taken from the first frame."""

    def __init__(self, path: str | Path, fps: float) -> None:
        self.path = Path(path)
        if self.path.suffix not in FOURCC:
            raise ValueError(f"{self.path}: a video is .avi, .mkv or .mp4")
        self.fps = float(fps)
        self.n_frames = 0  # handed over
        self.n_written = 0
        self.error: OSError | None = None
        self._renderer = None  # the last renderer sent to the encoder
        # started now: its interpreter and imports (~0.5 s) overlap the run's start
        # instead of delaying the first frames
        self._encoder: subprocess.Popen | None = self._start_encoder()

    def _start_encoder(self) -> subprocess.Popen:
        return subprocess.Popen(
            [sys.executable, "-c", _ENCODER, str(self.path), repr(self.fps)],
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
            bufsize=PIPE_BUFFER_BYTES,
        )

    def add(self, image) -> None:
        """Hand one frame over (an array, or a frame with a ``recipe()``)."""
        self.add_many([image])

    def add_many(self, images) -> None:
        """Hand frames over, in order: each run of frames that describe themselves as
        one message (the encoder draws and encodes a batch at once), others as pixels.
        ``n_frames`` counts what was handed over, also when a hand-over fails."""
        if self.error is not None:
            raise self.error
        if self._encoder is None:
            raise RuntimeError(f"{self.path}: the video was closed")
        scenes: list = []
        for image in images:
            recipe = getattr(image, "recipe", None)
            renderer, item = recipe() if recipe is not None else (None, None)
            if scenes and (recipe is None or renderer is not self._renderer):
                self._send_scenes(scenes)
            if recipe is None:
                self._send(("pixels", image))
                self.n_frames += 1
                continue
            if renderer is not self._renderer:
                self._send(("renderer", renderer))
                self._renderer = renderer
            scenes.append(item)
        if scenes:
            self._send_scenes(scenes)

    def _send_scenes(self, scenes: list) -> None:
        self._send(("scenes", list(scenes)), flush=True)
        self.n_frames += len(scenes)
        scenes.clear()

    def _send(self, message: tuple, flush: bool = False) -> None:
        try:
            pickle.dump(message, self._encoder.stdin, protocol=pickle.HIGHEST_PROTOCOL)
            if flush:  # the encoder starts on the batch now; a killed run loses none of it
                self._encoder.stdin.flush()
        except (BrokenPipeError, OSError):
            self._finish()  # the encoder stopped: its report says why
            if self.error is None:
                self.error = OSError(f"{self.path}: the video encoder stopped")
            raise self.error from None

    def _finish(self) -> None:
        """Close the pipe, wait for the encoder to write what it was sent, read its
        report: the frames written, or the error that stopped it."""
        encoder, self._encoder = self._encoder, None
        if encoder is None:
            return
        with contextlib.suppress(OSError):  # a broken pipe: the encoder's report says why
            encoder.stdin.close()
        report = encoder.stdout.read()
        encoder.wait()
        try:
            done = json.loads(report)
        except ValueError:
            done = {
                "written": 0,
                "error": f"the video encoder ended with code {encoder.returncode}",
            }
        self.n_written = int(done["written"])
        if done["error"] is not None and self.error is None:
            self.error = OSError(done["error"])

    def close(self) -> int:
        """Write what was handed over and close the file; the number of frames written."""
        self._finish()
        return self.n_written


def _serve() -> None:
    """The encoder process: ``argv`` path and rate; pickled frames on stdin until it
    closes; a JSON report (frames written, error or null) on stdout at the end."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # Ctrl-C is the run's to handle
    import av  # noqa: F401  (imported before the first frame, while the run starts)
    import cv2

    # one thread: OpenCV would split each frame's drawing over the cores, costing more
    # CPU (0.40 against 0.13-0.26 ms a frame, 2 cores) and taking the run's core
    cv2.setNumThreads(1)
    path, fps = Path(sys.argv[1]), float(sys.argv[2])
    writer, renderer, written, error = None, None, 0, None
    source = sys.stdin.buffer
    try:
        while True:
            try:
                kind, item = pickle.load(source)
            except (EOFError, pickle.UnpicklingError):
                break  # closed, or cut mid-frame by a killed run: what came is written
            if kind == "renderer":
                renderer = item
                continue
            if kind == "scenes":
                frames = [renderer.frame(scene) for scene in item]
                writer = writer or _Writer(path, fps, frames[0].shape)
                writer.write_scenes(frames, renderer)
                written += len(frames)
            else:
                writer = writer or _Writer(path, fps, item.shape)
                writer.write(item)
                written += 1
    except OSError as exc:
        error = str(exc)
    finally:
        if writer is not None:
            writer.release()
    with contextlib.suppress(OSError):  # a killed run reads no report
        sys.stdout.write(json.dumps({"written": written, "error": error}))
        sys.stdout.flush()


class _Writer:
    """Frames into the file through PyAV (FFmpeg's libavformat writes the container,
    OpenDML AVI past 1 GB included). Motion-JPEG frames are encoded by OpenCV
    (libjpeg-turbo, a restart at every row: ``labrig.recording.jpeg_rows``) and handed to the
    container as they are: 0.35-0.5 ms for a whole frame at 640x360 against 0.7-0.8 ms
    for FFmpeg's own MJPEG encoder behind OpenCV's ``VideoWriter``, which takes no
    encoded frames. MPEG-4 is encoded by FFmpeg."""

    def __init__(self, path: Path, fps: float, shape: tuple[int, ...]) -> None:
        import av  # only a run with a video needs it

        from labrig.recording.jpeg_rows import RowJpeg

        self._av = av
        height, width = shape[:2]
        self._rows = (
            RowJpeg(width, height, len(shape) == 3, JPEG_QUALITY)
            if FOURCC[path.suffix] == "MJPG"
            else None
        )
        self._path = path
        with self._errors():
            self._container = av.open(str(path), "w", format=_CONTAINERS[path.suffix])
        rate = Fraction(fps).limit_denominator(1001)
        self._stream = self._container.add_stream("mjpeg" if self._jpeg else "mpeg4", rate=rate)
        self._stream.width, self._stream.height = width, height
        self._stream.pix_fmt = "yuvj420p" if self._jpeg else "yuv420p"
        if not self._jpeg:  # FFmpeg's default (200 kbit/s) blurs the markers' edges
            self._stream.bit_rate = max(MPEG4_MIN_BIT_RATE, round(width * height * fps))
        self._time_base = 1 / rate
        self._colour = len(shape) == 3
        self._n = 0

    @property
    def _jpeg(self) -> bool:
        return self._rows is not None

    @contextlib.contextmanager
    def _errors(self):
        """FFmpeg's errors (the file is created at the first frame) as one OSError."""
        try:
            yield
        except (OSError, self._av.FFmpegError) as exc:
            raise OSError(f"{self._path}: cannot write this video here ({exc})") from exc

    def write(self, image) -> None:
        with self._errors():
            self._write(image)

    def write_scenes(self, frames: list, renderer) -> None:
        """Frames that render where they are read, with a renderer that knows which
        of their rows repeat (``row_keys``) and draws rows of many frames at once
        (``render_rows``): as Motion-JPEG, only the rows not seen before are drawn and
        encoded (``labrig.recording.jpeg_rows``); otherwise each frame is drawn whole."""
        keys = [renderer.row_keys(f, self._rows.row_px) if self._jpeg else None for f in frames]
        keyed = [i for i, k in enumerate(keys) if k is not None]
        with self._errors():
            jpegs = {}
            if keyed:
                keyed_frames = [frames[i] for i in keyed]
                encoded = self._rows.frames(
                    [keys[i] for i in keyed],
                    lambda spans: renderer.render_rows(keyed_frames, spans),
                )
                jpegs = dict(zip(keyed, encoded, strict=True))
            for i, frame in enumerate(frames):
                if i in jpegs:
                    self._mux_jpeg(jpegs[i])
                else:
                    self._write(np.asarray(frame))

    def _mux_jpeg(self, jpeg) -> None:
        packet = self._av.Packet(jpeg)
        packet.stream, packet.time_base = self._stream, self._time_base
        packet.pts = packet.dts = self._n
        packet.is_keyframe = True
        self._container.mux(packet)
        self._n += 1

    def _write(self, image) -> None:
        if self._jpeg:  # the same encoding as the assembled frames, whole
            self._mux_jpeg(self._rows.encode(image))
            return
        frame = self._av.VideoFrame.from_ndarray(image, format="bgr24" if self._colour else "gray")
        self._container.mux(self._stream.encode(frame))
        self._n += 1

    def release(self) -> None:
        with self._errors():
            if not self._jpeg:
                self._container.mux(self._stream.encode(None))  # the encoder's last frames
            self._container.close()
