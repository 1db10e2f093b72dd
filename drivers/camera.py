"""Frames from a camera or a video file, each timestamped, and the specimen's length
from them: the labrig LengthSource.

``FrameSource`` wraps a ``cv2.VideoCapture`` (or any capture-like object, such as
``labrig.sim.camera.SimCamera``). A live camera streams at its own rate into a few
driver buffers (V4L2: 4) and ``read()`` hands back the oldest, so a program that reads
more slowly than the camera streams gets frames up to 4 periods old. ``FrameSource``
therefore reads every frame in a reader thread (started through the shared clock) and
keeps only the latest; ``read()`` returns the newest frame not yet returned. Once
``take_frames()`` is used instead, the reader keeps every frame until it is taken: a
run's camera loop then wakes a few times a second for a batch instead of once per frame,
and on the simulated rig's virtual clock the reader goes from frame to frame without
handing time to another thread in between.

What a frame's time is, per backend (``stamp``):
- V4L2 (Linux): ``CAP_PROP_POS_MSEC`` is the buffer's capture time that the kernel
  stamps, on CLOCK_MONOTONIC, the clock ``RealClock`` reads (``time.monotonic``): the
  exposure's end, free of the transfer and of the reader's delay;
- SimCamera: the same semantics on the virtual clock (the frame's exposure time);
- other backends (MSMF, DSHOW, AVFoundation, GStreamer): their ``POS_MSEC`` is 0, a
  constant or the stream's own origin, so the frame is stamped with the
  shared clock read when the grab returns — late by the transfer, within a frame period;
- a video file: the file's own position, ``CAP_PROP_POS_MSEC`` after the read.

``configure`` asks for MJPG first (a UVC webcam opens in YUYV, which USB 2.0 carries at
about 10 fps at 1280x720), then sets the size, the rate, and locks exposure and focus
where asked, then reads them all back: a camera that silently stays at 640x480 would
make a scale measured at 1280x720 wrong, so a mismatch is refused in one line, and a
rate the camera cannot give in the pixel format it took says which format that is.
Without a manual exposure, V4L2's auto exposure is set (``CAP_PROP_AUTO_EXPOSURE``:
V4L2 takes 3, aperture priority, for auto and 1 for manual; a camera left in manual by
another program would otherwise keep that program's exposure), and on a camera
opened by its device node ``exposure_auto_priority`` is turned off
(``labrig.drivers.v4l2_control``): with it on, auto exposure lowers the real frame rate
in dim light while ``CAP_PROP_FPS`` still reports the nominal one. What the camera
really gives is measured from the frames' stamps (``measured_fps``).

A camera is an index, a ``/dev/video*`` node or any path under ``/dev`` that leads to
one: the ``/dev/v4l/by-id/...`` links udev makes stay the same whichever
``/dev/videoN`` the camera gets when it is plugged in again. The link is resolved and
the node it names opened with the V4L2 backend.

A capture stamp is checked against the shared clock read at the grab: a stamp ahead
of it, far behind it (more than the driver's queue of frames), or not after the
previous one means the camera's clock jumped, and the stream is failed rather than
recorded out of time. The first ``warmup_frames`` frames
after the stream starts are dropped: a webcam's auto exposure settles over them (its
first frame is nearly black, and a scale taken from it would fail).

``CameraLength`` = frames + ``MarkerTracker`` + a pixel-to-mm scale. A live camera's
batches (``read_new``) are tracked in a process of their own (``TrackerProcess``), each
while the next is taken, so the tracking runs on another core instead of taking the
run's interpreter lock; a single frame (``read``, a video file) is tracked in place.
The scale is given (``mm_per_px``) or taken from the first frame, whose markers are a
known distance apart (``reference_distance_mm``). It assumes the markers move in a plane
square to the camera's axis, where one scale holds across the frame.
"""

from __future__ import annotations

import logging
import os
import re
import threading
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Literal

import cv2
import numpy as np

from labrig.drivers.markers import MarkerFix, MarkerTracker, mm_per_px_from_reference
from labrig.drivers.tracker_process import TrackerProcess
from labrig.drivers.v4l2_control import V4L2_CID_EXPOSURE_AUTO_PRIORITY, set_control
from labrig.errors import DeviceError, InputError
from labrig.rig.devices import LengthSample
from labrig.time.clock import Clock, ClockThread

DEVICE_PATH = re.compile(r"^/dev/video\d+$")
log = logging.getLogger(__name__)
# V4L2 exposure modes as OpenCV passes them (CAP_PROP_AUTO_EXPOSURE)
V4L2_MANUAL_EXPOSURE, V4L2_AUTO_EXPOSURE = 1.0, 3.0
DEFAULT_WARMUP_FRAMES = 5
# no frame for this long (clock seconds) from a live camera is a device fault
FRAME_TIMEOUT_S = 2.0
# the pixel format asked for first: compressed, so USB 2.0 carries 1280x720 at 30 fps
PREFERRED_FOURCC = "MJPG"
# a capture stamp may lead the clock read after the grab by rounding only, and trail it
# by the frames queued in the driver (V4L2: 4) and the reader's delay
STAMP_LEAD_S = 0.01
STAMP_LAG_FRAMES = 6
STAMP_LAG_MIN_S = 1.0
# frames tried for the reference scale before the run is refused
CALIBRATION_FRAMES = 10
# A reader nobody has asked for a frame for this long (clock seconds) stops; the next
# read() starts it again. An abandoned FrameSource (one never closed after an error)
# would otherwise read forever, and on a virtual clock a lone reader runs flat out.
READER_IDLE_S = 10.0


@dataclass(frozen=True)
class Frame:
    t_s: float
    image: np.ndarray


@dataclass(frozen=True)
class CameraSettings:
    """What a live camera is asked for (None: leave the camera's own setting)."""

    width: int | None = 1280
    height: int | None = 720
    fps: float | None = None
    exposure: float | None = None  # manual exposure in the backend's units; None: auto
    focus: float | None = None  # manual focus in the backend's units; None: leave it
    fourcc: str | None = PREFERRED_FOURCC  # the pixel format asked for; None: leave it


class FrameSource:
    """Timestamped frames from a capture. ``clock`` given: a live source on the shared
    clock, read in a reader thread; ``clock=None``: a file stamped with its own position.

    ``stamp="capture"``: the capture's ``CAP_PROP_POS_MSEC`` is the capture time on the
    shared clock (V4L2, SimCamera); ``"host"``: the clock read when the grab returns.
    """

    def __init__(
        self,
        capture: Any,
        *,
        clock: Clock | None,
        name: str,
        stamp: Literal["capture", "host"] = "host",
        warmup_frames: int = 0,
    ) -> None:
        self.capture = capture
        self.clock = clock
        self.name = name
        self.stamp = stamp
        self.warmup_frames = int(warmup_frames)
        self.n_frames = 0  # frames returned by read()
        self.n_grabbed = 0  # frames the reader took from the camera (warm-up included)
        self._lock = threading.Lock()
        self._latest: Frame | None = None
        self._latest_seq = 0
        self._taken_seq = 0
        self._error: Exception | None = None
        self._stopping = False
        self._reader: ClockThread | None = None
        self._last_read_s = float("-inf")
        self._last_grab_s = float("-inf")
        self._keep_all = False  # take_frames() in use: every frame kept until taken
        self._kept: list[Frame] = []
        self.fourcc = ""  # the pixel format the camera reports, once configured
        self._last_stamp_s = float("-inf")
        # the first and the newest frame's stamp, and the frames between (warm-up left
        # out): the rate the camera really gives
        self._first_frame_s = float("nan")
        self._newest_frame_s = float("nan")
        self._n_stamped = 0

    @classmethod
    def open(
        cls, source: int | str | Path, clock: Clock, settings: CameraSettings | None = None
    ) -> FrameSource:
        """A camera (an int, a string of digits: its device index, or a path under /dev
        such as /dev/video0 or a /dev/v4l/by-id/... link) or a video file."""
        if isinstance(source, int) or (isinstance(source, str) and source.isdigit()):
            return cls.open_camera(int(source), clock, settings)
        if is_device_path(source):
            return cls.open_camera(str(source), clock, settings)
        return cls.open_file(source)

    @classmethod
    def open_camera(
        cls, device: int | str, clock: Clock, settings: CameraSettings | None = None
    ) -> FrameSource:
        """A live camera by index or device path (a link is resolved to the node it
        names), configured with ``settings``."""
        node = device_node(device)
        named = str(device) if str(node) == str(device) else f"{device} ({node})"
        if isinstance(device, str) and not Path(node).exists():
            raise DeviceError(f"camera {named}: no such device (is the camera plugged in?)")
        # a node by path needs the V4L2 backend; an index lets OpenCV choose
        capture = cv2.VideoCapture(node, cv2.CAP_V4L2 if isinstance(device, str) else 0)
        if not capture.isOpened():
            capture.release()
            raise DeviceError(
                f"camera {named} could not be opened: check that it is connected and no "
                "other program uses it, or run without hardware with --sim"
            )
        source = cls.live(capture, clock, f"camera {device}")
        settings = settings or CameraSettings()
        try:
            source.configure(settings)
        except DeviceError:
            capture.release()
            raise
        if settings.exposure is None and source.stamp == "capture":
            # V4L2 (Linux) numbers its cameras as its nodes: index N is /dev/videoN
            source.keep_the_rate(node if isinstance(node, str) else f"/dev/video{node}")
        return source

    @classmethod
    def live(
        cls, capture: Any, clock: Clock, name: str, warmup_frames: int = DEFAULT_WARMUP_FRAMES
    ) -> FrameSource:
        """A live capture, its stamp chosen by its backend (module docstring)."""
        backend = capture.getBackendName() if hasattr(capture, "getBackendName") else ""
        stamp = "capture" if backend == "V4L2" else "host"
        return cls(capture, clock=clock, name=name, stamp=stamp, warmup_frames=warmup_frames)

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

    # --- configuration -----------------------------------------------------------------
    def configure(self, settings: CameraSettings) -> None:
        """Set what ``settings`` asks for, then read each back; a mismatch is refused."""
        c = self.capture
        if settings.fourcc is not None:
            # first: on V4L2 a format change resets the rate
            c.set(cv2.CAP_PROP_FOURCC, cv2.VideoWriter_fourcc(*settings.fourcc))
        asked: list[tuple[str, int, float]] = []
        if settings.width is not None:
            asked.append(("width", cv2.CAP_PROP_FRAME_WIDTH, float(settings.width)))
        if settings.height is not None:
            asked.append(("height", cv2.CAP_PROP_FRAME_HEIGHT, float(settings.height)))
        if settings.fps is not None:
            asked.append(("fps", cv2.CAP_PROP_FPS, float(settings.fps)))
        if settings.exposure is not None:
            c.set(cv2.CAP_PROP_AUTO_EXPOSURE, V4L2_MANUAL_EXPOSURE)
            asked.append(("exposure", cv2.CAP_PROP_EXPOSURE, float(settings.exposure)))
        elif self.stamp == "capture":  # V4L2's modes; other backends number them otherwise
            asked.append(("auto exposure", cv2.CAP_PROP_AUTO_EXPOSURE, V4L2_AUTO_EXPOSURE))
        if settings.focus is not None:
            c.set(cv2.CAP_PROP_AUTOFOCUS, 0.0)
            asked.append(("focus", cv2.CAP_PROP_FOCUS, float(settings.focus)))
        for _, prop, value in asked:
            c.set(prop, value)
        self.fourcc = fourcc_text(c.get(cv2.CAP_PROP_FOURCC))
        for what, prop, value in asked:
            got = float(c.get(prop))
            if what == "fps" and got == 0.0:
                continue  # the backend does not report a rate: nothing to compare
            if abs(got - value) > 0.01 * max(abs(value), 1.0):
                if what == "fps" and self.fourcc and self.fourcc != settings.fourcc:
                    size = (
                        f"{c.get(cv2.CAP_PROP_FRAME_WIDTH):g}x{c.get(cv2.CAP_PROP_FRAME_HEIGHT):g}"
                    )
                    raise DeviceError(
                        f"{self.name}: streams {self.fourcc}, not {settings.fourcc}, and "
                        f"gives {got:g} fps at {size} where {value:g} were asked: lower "
                        "camera.fps or camera.width/height in the rig file, or use a camera "
                        "that streams MJPG (v4l2-ctl --list-formats-ext lists its formats)"
                    )
                if what == "auto exposure":
                    raise DeviceError(
                        f"{self.name}: auto exposure (V4L2 mode 3) was asked, the camera "
                        f"stays in mode {got:g}: give camera.exposure in the rig file for a "
                        "manual exposure (v4l2-ctl --all lists its range)"
                    )
                raise DeviceError(
                    f"{self.name}: asked for {what} {value:g}, the camera gives {got:g} "
                    f"(set camera.{what} in the rig file to what it supports; "
                    "v4l2-ctl --all lists it)"
                )

    def keep_the_rate(self, node: str) -> None:
        """Turn ``exposure_auto_priority`` off on the V4L2 node ``node``, so auto
        exposure cannot lower the frame rate; a camera without the control (or a
        system that cannot set it) is logged, and ``measured_fps`` tells the rate."""
        problem = set_control(node, V4L2_CID_EXPOSURE_AUTO_PRIORITY, 0)
        if problem is not None:
            log.warning(
                "%s: exposure_auto_priority not turned off (%s): in dim light auto "
                "exposure may lower the frame rate",
                self.name,
                problem,
            )

    # --- reading -----------------------------------------------------------------------
    def read(self) -> Frame | None:
        """The next frame: from a file, the next in it (None at its end); from a camera,
        the newest frame not returned before, waiting on the clock for one."""
        if self.clock is None:
            return self._read_file()
        timeout_s = self._start_reading()
        while True:
            grabbed = self.n_grabbed
            self.clock.wait_for(
                lambda: self._latest_seq > self._taken_seq or self._error is not None,
                timeout_s=timeout_s,
            )
            with self._lock:
                if self._latest_seq > self._taken_seq:
                    self._taken_seq = self._latest_seq
                    self.n_frames += 1
                    return self._latest
                error = self._error
            if error is not None:
                raise error
            if self.n_grabbed == grabbed:  # not even a warm-up frame came meanwhile
                raise DeviceError(f"{self.name} sent no frame for {timeout_s:g} s")

    def take_frames(self) -> list[Frame]:
        """Every frame of a live camera since the last call, oldest first (an empty list
        when no new frame came; the first call starts the reader); never waits. Raises
        what stopped the reader, or a DeviceError when the camera sent nothing, not even
        a warm-up frame, for the frame timeout."""
        if self.clock is None:
            raise RuntimeError("take_frames: a live source only (a file is read())")
        self._keep_all = True
        timeout_s = self._start_reading()
        with self._lock:
            frames, self._kept = self._kept, []
            error = self._error
        if frames:
            return frames
        if error is not None:
            raise error
        if self.clock.now() - self._last_grab_s > timeout_s:
            raise DeviceError(f"{self.name} sent no frame for {timeout_s:g} s")
        return []

    def _start_reading(self) -> float:
        """(Re)start the reader if it is not running; the frame timeout (clock s)."""
        now_s = self.clock.now()
        self._last_read_s = now_s
        if self._reader is None or self._reader.done:
            self._last_grab_s = now_s
            self._reader = self.clock.start_thread(self._read_frames, f"{self.name} reader")
        fps = float(self.capture.get(cv2.CAP_PROP_FPS) or 0.0)
        return max(FRAME_TIMEOUT_S, 3.0 / fps) if fps > 0 else FRAME_TIMEOUT_S

    def _read_frames(self) -> None:
        """The reader thread: every frame the camera streams, the latest kept. Whatever
        ends it early is kept for ``read()`` to raise: a reader that died quietly would
        look like a camera that stopped sending."""
        try:
            self._read_every_frame()
        except DeviceError as exc:
            with self._lock:
                self._error = exc
        except Exception as exc:
            with self._lock:
                self._error = DeviceError(f"{self.name} reader failed: {exc!r}")

    def _read_every_frame(self) -> None:
        while not self._stopping and self.clock.now() - self._last_read_s < READER_IDLE_S:
            ok, image = self.capture.read()
            t_host_s = self.clock.now()  # right after the grab, before any processing
            if not ok or image is None:
                with self._lock:
                    self._error = DeviceError(
                        f"{self.name} returned no frame: is it still connected?"
                    )
                return
            self.n_grabbed += 1
            self._last_grab_s = t_host_s
            if self.n_grabbed <= self.warmup_frames:
                continue  # the exposure is still settling
            t_s = t_host_s
            if self.stamp == "capture":
                t_capture_s = self.capture.get(cv2.CAP_PROP_POS_MSEC) / 1000.0
                # a backend that gave stamps and now gives none (0, or less) has jumped
                if t_capture_s > 0 or self._last_stamp_s > float("-inf"):
                    self._check_stamp(t_capture_s, t_host_s)
                    t_s = t_capture_s
            frame = Frame(t_s=t_s, image=image)
            with self._lock:
                if self._n_stamped == 0:
                    self._first_frame_s = t_s
                self._newest_frame_s = t_s
                self._n_stamped += 1
                if self._keep_all:
                    self._kept.append(frame)
                    self.n_frames += 1
                else:
                    self._latest = frame
                    self._latest_seq += 1

    def _check_stamp(self, t_capture_s: float, t_host_s: float) -> None:
        """A capture stamp must lie between the queue's depth before the grab and the
        grab, and after the previous frame's (module docstring)."""
        fps = float(self.capture.get(cv2.CAP_PROP_FPS) or 0.0)
        lag_s = max(STAMP_LAG_MIN_S, STAMP_LAG_FRAMES / fps) if fps > 0 else STAMP_LAG_MIN_S
        problem = None
        if t_capture_s > t_host_s + STAMP_LEAD_S:
            problem = f"{t_capture_s - t_host_s:.2f} s ahead of"
        elif t_capture_s < t_host_s - lag_s:
            problem = f"{t_host_s - t_capture_s:.2f} s behind"
        elif t_capture_s <= self._last_stamp_s:
            problem = f"not after the previous frame's ({self._last_stamp_s:.3f} s), against"
        if problem is not None:
            raise DeviceError(
                f"{self.name}: frame stamped {t_capture_s:.3f} s, {problem} the host clock "
                f"({t_host_s:.3f} s): the camera's clock jumped; reconnect the camera"
            )
        self._last_stamp_s = t_capture_s

    @property
    def measured_fps(self) -> float | None:
        """The frame rate the camera really gave, from the stamps of its frames since
        the stream started (warm-up left out); None before two frames. It can be below
        ``CAP_PROP_FPS``: auto exposure with ``exposure_auto_priority`` on lowers the
        rate in dim light and the property still reports the nominal one."""
        with self._lock:
            n, first_s, newest_s = self._n_stamped, self._first_frame_s, self._newest_frame_s
        if n < 2 or not newest_s > first_s:
            return None
        return (n - 1) / (newest_s - first_s)

    @property
    def last_grab_s(self) -> float:
        """The clock time of the newest frame taken from the camera (warm-up included)."""
        return self._last_grab_s

    @property
    def error(self) -> Exception | None:
        """What stopped the reader, if anything did."""
        return self._error

    def _read_file(self) -> Frame | None:
        ok, image = self.capture.read()
        if not ok or image is None:
            if self.n_frames == 0:
                raise InputError(f"{self.name}: no frame could be read (corrupt or empty video)")
            return None
        t_s = self.capture.get(cv2.CAP_PROP_POS_MSEC) / 1000.0
        self.n_frames += 1
        return Frame(t_s=t_s, image=image)

    def close(self) -> None:
        """Stop the reader (it ends after its current frame), then release the capture."""
        self._stopping = True
        reader = self._reader
        if reader is not None and self.clock is not None:
            self.clock.wait_for(lambda: reader.done, timeout_s=FRAME_TIMEOUT_S)
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
        # a live camera's frames are tracked in a process of their own (``read_new``),
        # started now: its start-up (~0.2 s) overlaps the caller's before the first batch
        self._process: TrackerProcess | None = None
        self._in_hand: list[Frame] = []  # the frames of the batch being tracked there
        if self.waits_for_frames:
            self._process = TrackerProcess(self.tracker, f"{frames.name} tracker")

    @property
    def waits_for_frames(self) -> bool:
        """True when ``read`` waits for the camera's next frame (a live camera): its
        reader needs no pacing of its own. A video file is read as fast as asked."""
        return not self.frames.is_file

    def read(self) -> LengthSample | None:
        frame = self.frames.read()
        return None if frame is None else self._measure(frame)

    def read_new(self) -> list[LengthSample]:
        """Every frame of a live camera up to the call before this one, measured; never
        waits for the camera.

        The frames taken now (``FrameSource.take_frames``) are handed as one batch to
        the tracker's own process (``TrackerProcess``, ``MarkerTracker.track_many``),
        which measures them while the caller goes on; the samples returned are those of
        the batch handed over at the previous call, oldest first (waiting for them if
        they are not done yet). ``read_rest`` returns the batch still in hand."""
        frames = self.frames.take_frames()
        done = self._collect()
        if frames:
            if self._process is None:
                raise DeviceError(f"{self.frames.name}: its tracker was closed")
            self._process.submit([frame.image for frame in frames])
            self._in_hand = frames
        return done

    def read_rest(self) -> list[LengthSample]:
        """``read_new``, then the frames it handed over, waited for: every frame taken so
        far, measured. A camera that failed still has its last batch measured."""
        try:
            done = self.read_new()
        except DeviceError:
            done = []  # nothing new came; the batch in hand is still there
        return done + self._collect()

    def calibrate(self) -> None:
        """Take the scale from the first frame (after the warm-up) in which both markers
        are found, a known ``reference_distance_mm`` apart: before a run moves anything,
        so a camera that cannot see them refuses the run with nothing moved. A given
        ``mm_per_px``, or a video file (its first frame is the reference when read),
        needs nothing."""
        if self.mm_per_px is not None or self.frames.is_file:
            return
        statuses = []
        for _ in range(CALIBRATION_FRAMES):
            fix = self.tracker.track(self.frames.read().image)
            if fix.ok and fix.distance_px > 0:
                self.mm_per_px = mm_per_px_from_reference(fix, self.reference_distance_mm)
                return
            statuses.append(fix.status)
        raise DeviceError(
            f"{self.frames.name}: no scale: both markers were not found in "
            f"{CALIBRATION_FRAMES} frames (last: {statuses[-1]}) for the reference distance "
            f"of {self.reference_distance_mm:g} mm; check the camera's view, focus and "
            "light, or give camera.mm_per_px in the rig file"
        )

    @property
    def measured_fps(self) -> float | None:
        """The camera's real frame rate (``FrameSource.measured_fps``), for the run file."""
        return self.frames.measured_fps

    def newest_frame_s(self) -> float:
        """The clock time of the camera's newest frame (for the signal watch)."""
        return self.frames.last_grab_s

    def stream_fault(self) -> str | None:
        """Why the camera's stream stopped, once it has (None while it streams)."""
        error = self.frames.error
        return None if error is None else str(error)

    def _collect(self) -> list[LengthSample]:
        frames, self._in_hand = self._in_hand, []
        if not frames:
            return []
        fixes = self._process.collect()
        return [self._sample(frame, fix) for frame, fix in zip(frames, fixes, strict=True)]

    def _measure(self, frame: Frame) -> LengthSample:
        return self._sample(frame, self.tracker.track(frame.image))

    def _sample(self, frame: Frame, fix: MarkerFix) -> LengthSample:
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
            image=frame.image,
        )

    def close(self) -> None:
        """Stop the camera and the tracker's process."""
        self.frames.close()
        self.close_tracker()

    def close_tracker(self) -> None:
        """End the tracker's process (a batch in hand is dropped: ``read_rest`` first)."""
        process, self._process = self._process, None
        self._in_hand = []
        if process is not None:
            process.close()


def fourcc_text(code: float) -> str:
    """A FOURCC as OpenCV reports it (a float of the packed code) as its four letters;
    "" when the backend reports none."""
    value = int(code)
    return "" if value <= 0 else value.to_bytes(4, "little").decode("ascii", "replace").strip()


def is_device_path(source: str | Path) -> bool:
    """A path that names a device rather than a video file: under /dev itself, or a
    link that leads there (``/dev/v4l/by-id/...``, or one of the user's own)."""
    path = str(source)
    return path.startswith("/dev/") or os.path.realpath(path).startswith("/dev/")


def device_node(device: int | str) -> int | str:
    """The node a device path leads to (a by-id link resolved: OpenCV's V4L2 backend
    opens the node it is given); an index as it is."""
    return device if isinstance(device, int) else os.path.realpath(device)
