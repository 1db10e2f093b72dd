"""Marker tracking in a process of its own, a batch of frames at a time, overlapped with
the caller: the camera's tracking runs on another core instead of taking the run's
interpreter lock.

A ``TrackerProcess`` owns a ``MarkerTracker`` in a child process
(``python -c 'labrig.drivers.tracker_process._serve()'``), fed through a pipe as the
run's video encoder is (``labrig.recording.video``). ``submit`` hands a batch over and returns at
once; ``collect`` waits for the fixes of the batch handed over before. A caller that
submits batch k and then collects batch k-1 has each batch tracked while it goes on
with its own work: on the simulated rig that is the next second of the run, in which
the camera loop's tracking (its window rendering included) was a third of the run's CPU.

Frames that describe themselves (``recipe()``: a simulated frame, a few numbers) are
sent as those descriptions and drawn in the child where the tracker reads them; any
other frame (a real camera's) is sent as its pixels. The child keeps the tracker's state
(the markers' last positions) from batch to batch, so the fixes are exactly those of
``MarkerTracker.track_many`` on the same batches in the caller's process.

The child never touches a clock: on the simulated rig's virtual clock a caller waiting
in ``collect`` holds time still (a participant blocked outside the clock), so when the
fixes arrive does not change what they are. Every wait has a host timeout. A run killed
outright closes the pipe and the child ends at its next read.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
from collections.abc import Sequence
from multiprocessing.connection import Connection

from labrig.drivers.markers import MarkerFix, MarkerTracker
from labrig.errors import DeviceError

# A batch (a second of frames) is tracked in milliseconds; no answer for this long
# (host seconds, a busy machine included) means the child hung.
REPLY_TIMEOUT_S = 60.0
# How much lower the child runs than the run (``os.nice``). Not much: beside two
# CPU-bound processes, a child at niceness 10 gets so little of the machine that the
# run waits for it, longer than with the tracking in the run's own process.
TRACKER_NICENESS = 4
_CHILD = "from labrig.drivers.tracker_process import _serve; _serve()"


class TrackerProcess:
    """``tracker`` (its settings and state) run in a child process, started now: its
    interpreter and imports (~0.2 s) overlap the caller's work before the first batch.
    Messages go as ``multiprocessing.connection`` frames over two pipes: a reply is
    waited for with a timeout and read whole, whatever else is already in the pipe."""

    def __init__(self, tracker: MarkerTracker, name: str = "marker tracker") -> None:
        self.name = name
        self._pending = 0  # batches handed over and not yet collected
        self._renderer = None  # the last renderer sent
        from_parent, to_child = os.pipe()
        from_child, to_parent = os.pipe()
        try:
            self._child: subprocess.Popen | None = subprocess.Popen(
                [sys.executable, "-c", _CHILD], stdin=from_parent, stdout=to_parent
            )
        finally:
            os.close(from_parent)
            os.close(to_parent)
        self._to_child = Connection(to_child, readable=False)
        self._from_child = Connection(from_child, writable=False)
        self._send(("tracker", tracker))

    @property
    def pending(self) -> int:
        return self._pending

    def submit(self, images: Sequence) -> None:
        """Hand a batch of consecutive frames over to be tracked (``track_many``)."""
        items = []
        for image in images:
            recipe = getattr(image, "recipe", None)
            if recipe is None:
                items.append(image)
                continue
            renderer, scene = recipe()
            if renderer is not self._renderer:
                self._send(("renderer", renderer))
                self._renderer = renderer
            items.append(scene)
        self._send(("frames", items))
        self._pending += 1

    def collect(self) -> list[MarkerFix]:
        """The fixes of the oldest batch not yet collected, waiting for them."""
        if self._pending == 0:
            raise RuntimeError(f"{self.name}: no batch to collect")
        self._alive()
        try:
            if not self._from_child.poll(REPLY_TIMEOUT_S):
                self.close()
                raise DeviceError(f"{self.name}: no answer within {REPLY_TIMEOUT_S:g} s")
            kind, item = self._from_child.recv()
        except (EOFError, OSError):
            self.close()
            raise DeviceError(f"{self.name}: its process ended") from None
        self._pending -= 1
        if kind == "error":
            raise DeviceError(f"{self.name} failed: {item}")
        return [MarkerFix(*row) for row in item]

    def close(self) -> None:
        """End the child (it finishes the batch in hand); batches not collected are
        dropped."""
        child, self._child = self._child, None
        if child is None:
            return
        self._to_child.close()  # the child's next read ends it
        try:
            child.wait(timeout=REPLY_TIMEOUT_S)
        except subprocess.TimeoutExpired:
            child.kill()
            child.wait()
        self._from_child.close()

    def _alive(self) -> None:
        if self._child is None:
            raise DeviceError(f"{self.name}: closed")

    def _send(self, message: tuple) -> None:
        self._alive()
        try:
            self._to_child.send(message)
        except OSError:
            self.close()
            raise DeviceError(f"{self.name}: its process ended") from None


def _serve() -> None:
    """The child: a tracker, then batches of frames (pixels, or scenes of the last
    renderer) on stdin until it closes; for each batch its fixes (or the error) on the
    pipe that was stdout (stdout itself goes to stderr: a library's message printed
    there would otherwise corrupt a reply)."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # Ctrl-C is the run's to handle
    import cv2

    # a little below the run's priority: a batch has a camera period to be tracked in,
    # while the run's threads hand over to each other and to the kernel (a serial
    # exchange on a pseudo-terminal) many times a millisecond
    os.nice(TRACKER_NICENESS)

    # one thread: OpenCV would split each small window's work over the cores, costing
    # more CPU and taking the run's core
    cv2.setNumThreads(1)
    source = Connection(0, writable=False)
    sink = Connection(os.dup(1), readable=False)
    os.dup2(2, 1)
    tracker, renderer = None, None
    while True:
        try:
            kind, item = source.recv()
        except (EOFError, OSError):
            return  # closed: the run ended, or was killed
        if kind == "tracker":
            tracker = item
            continue
        if kind == "renderer":
            renderer = item
            continue
        try:
            frames = [scene if hasattr(scene, "shape") else renderer.frame(scene) for scene in item]
            reply = ("fixes", [_row(fix) for fix in tracker.track_many(frames)])
        except Exception as exc:  # the caller reports it as the camera's fault
            reply = ("error", repr(exc))
        sink.send(reply)


def _row(fix: MarkerFix) -> tuple:
    return (fix.x1_px, fix.y1_px, fix.x2_px, fix.y2_px, fix.ok, fix.status)
