"""The acquisition threads: the DAQ stream, the pump poll, the camera, and the watch.

Each loop runs in its own thread on the rig's clock (``Clock.start_thread``) and reads
its device every period, paced by deadlines. Every reading is judged by the interlocks
first, in the loop that read it, and only then queued for the run file (which a
thread of its own writes: ``labrig.run.background_writer``): neither a busy main loop
nor a slow disk can delay a stop. A fourth loop watches that the pressure samples and
the camera's frames keep coming (``labrig.run.signal_watch``), since a dead device
sends nothing to trip on; the camera is watched from its first frame on.
"""

from __future__ import annotations

import bisect
import contextlib
import itertools
import math
import threading
from collections.abc import Callable
from dataclasses import dataclass, field
from operator import itemgetter

import numpy as np

from labrig.config.protocol import Protocol
from labrig.errors import LabrigError
from labrig.recording.video import VideoRecorder
from labrig.rig.devices import LengthSample, PressureBlock, PumpState, Rig
from labrig.run.background_writer import BackgroundWriter
from labrig.run.interlocks import InterlockMonitor
from labrig.run.signal_watch import SignalWatch
from labrig.time.clock import ClockThread


@dataclass
class Timing:
    """Loop periods and deadlines, in clock seconds."""

    pressure_period_s: float = 0.2
    pump_period_s: float = 0.2
    # a live camera's frames are taken from its reader thread in batches this often,
    # each tracked in the tracker's process while the next is taken, and recorded when
    # the next is taken: a batch's tracking costs mostly its calls, not its pixels, so a
    # second's 30 frames cost little more than 0.2 s's 6 (the combined actuator at
    # 30 fps: 8.0 s of tracking CPU at 0.2 s, 5.4 s at 1 s); the markers-lost interlock,
    # which allows 10 s, trips at most two periods later than its frame
    camera_period_s: float = 1.0
    progress_period_s: float = 0.5
    max_marker_loss_s: float = 10.0
    target_grace_s: float = 5.0
    first_readings_s: float = 10.0
    loop_exit_s: float = 5.0
    # a signal quiet this long (no pressure sample; no camera frame, or three frame
    # periods if longer) is a dead device
    signal_timeout_s: float = 0.5
    # a UVC webcam takes 0.3-1 s from the stream's start to its first frame: it is
    # watched from that frame on, and this long is allowed for it
    camera_start_s: float = 3.0
    watch_period_s: float = 0.1
    # the run file's queued writes may take this long after the stop (a slow disk)
    writer_drain_s: float = 60.0


@dataclass
class Latest:
    """The newest readings, for the main loop's decisions and the progress display."""

    pressure_kpa: float = float("nan")
    length_mm: float = float("nan")
    volume_ml: float = 0.0
    pump_state: PumpState = PumpState.IDLE
    pump_t_s: float = float("-inf")
    pump_seq: int = -1
    pressure_blocks: int = 0
    pressure_samples: int = 0
    lock: threading.Lock = field(default_factory=threading.Lock)


class Acquisition:
    """The loops of one run, the readings they keep, and the repetition they record
    into. ``hurry()`` says when the run must stop now (waits for nothing)."""

    def __init__(
        self,
        rig: Rig,
        protocol: Protocol,
        timing: Timing,
        monitor: InterlockMonitor,
        writer: BackgroundWriter,
        video: VideoRecorder | None,
        hurry: Callable[[], bool],
    ) -> None:
        self.rig = rig
        self.clock = rig.clock
        self.protocol = protocol
        self.timing = timing
        self.monitor = monitor
        self.writer = writer
        self.file = writer.writer  # whose methods the writer's thread calls
        self.video = video
        self.hurry = hurry
        self.watch = SignalWatch(rig.clock)
        self.latest = Latest()
        self.repetition = 1
        # (start time, repetition) of each repetition entered, in order: frames are
        # recorded after the fact, into the repetition of their time
        self.repetition_starts: list[tuple[float, int]] = []
        # the pump's counters and the monitor's volume offset change together
        self.volume_lock = threading.Lock()
        self.motion_seq = 0  # counts motion starts: the pump poll re-phases on each
        self.acquiring = False
        self.shutdown_errors: list[str] = []
        self._stop_loops = threading.Event()
        self._stopped_at_s = math.inf  # when the loops were last told to stop
        self._threads: list[ClockThread] = []
        self._marker_lost_since: float | None = None

    # --- start and stop ------------------------------------------------------------
    def start(self) -> None:
        """Start the loops (if not running) and wait for their first readings."""
        if self.acquiring:
            return
        self._stop_loops.clear()
        camera = self.rig.length is not None and self.protocol.acquisition.camera_fps > 0
        if camera and hasattr(self.rig.length, "calibrate"):
            self.rig.length.calibrate()  # a scale taken from a frame, before anything moves
        self.rig.pressure.start(self.protocol.acquisition.pressure_rate_hz)
        self.acquiring = True
        self.watch.expect("pressure", self.timing.signal_timeout_s)
        loops = [self._pressure_loop, self._pump_loop, self._watch_loop]
        if camera:
            loops.append(self._camera_loop)
        self._threads = [self.clock.start_thread(loop, loop.__name__.strip("_")) for loop in loops]
        self._wait_for_first_readings()

    def _wait_for_first_readings(self) -> None:
        """Interlocks see a pressure block and a pump status before anything moves."""
        latest = self.latest
        self.clock.wait_for(
            lambda: (
                self.monitor.tripped is not None
                or (latest.pressure_samples > 0 and latest.pump_t_s > float("-inf"))
            ),
            timeout_s=self.timing.first_readings_s,
        )
        if not self.monitor.tripped and latest.pressure_samples == 0:
            self.monitor.trip(
                f"no pressure readings within {self.timing.first_readings_s:g} s of starting",
                "faulted",
            )

    def stop(self) -> None:
        """Stop the loops; record what the DAQ's buffer still holds; stop the DAQ."""
        self._stopped_at_s = self.clock.now()
        self._stop_loops.set()
        threads = self._threads
        # a second stop request waits for nothing: the loops stop at their next wake-up
        self.clock.wait_for(
            lambda: self.hurry() or all(thread.done for thread in threads),
            timeout_s=self.timing.loop_exit_s,
        )
        self._threads = []
        self.watch.forget()
        if self.acquiring:
            self.acquiring = False
            try:
                self._record_pressure(self.rig.pressure.read())  # what the buffer still holds
            except (LabrigError, OSError) as exc:
                self.shutdown_errors.append(f"pressure read at stop: {exc}")
            try:
                self.rig.pressure.stop()
            except (LabrigError, OSError) as exc:
                # keep going: the file must still be finalised; the error is reported
                self.shutdown_errors.append(f"pressure stop: {exc}")

    def start_motion(self) -> int:
        """A motion starts: only a status requested after this may say it has ended."""
        with self.latest.lock:
            self.motion_seq += 1
            return self.motion_seq

    def repetition_at(self, t_s: float) -> int:
        """The repetition that was running at ``t_s`` (the first one before any)."""
        if not self.repetition_starts:
            return self.repetition
        i = bisect.bisect_right(self.repetition_starts, t_s, key=itemgetter(0))
        return self.repetition_starts[max(i - 1, 0)][1]

    # --- the loops -----------------------------------------------------------------
    def _pressure_loop(self) -> None:
        self._device_loop("pressure", self.timing.pressure_period_s, self._read_pressure)

    def _pump_loop(self) -> None:
        # polled at once when a motion starts, then every period from there: identical
        # steps are seen to end after identical times
        self._device_loop(
            "pump", self.timing.pump_period_s, self._read_pump, rephase=lambda: self.motion_seq
        )

    def _camera_loop(self) -> None:
        # a live camera's reader thread measures every frame it streams (at the
        # protocol's camera_fps) and the loop records them in batches; a video file
        # standing in for the camera is read and measured at camera_fps
        if getattr(self.rig.length, "waits_for_frames", False):
            since_s = self.clock.now()
            self.watch.expect("camera", self._frame_allowance_s(), self.timing.camera_start_s)
            self._device_loop(
                "camera", self.timing.camera_period_s, lambda: self._read_lengths(since_s)
            )
            if not self.hurry():
                # the batch still being measured and the frames since, up to the stop or
                # the camera's fault (already reported: a second error changes nothing)
                with contextlib.suppress(LabrigError, OSError):
                    self._read_lengths(since_s, self._stopped_at_s, rest=True)
        else:
            self._device_loop(
                "camera", 1.0 / self.protocol.acquisition.camera_fps, self._read_length
            )

    def _frame_allowance_s(self) -> float:
        return max(self.timing.signal_timeout_s, 3.0 / self.protocol.acquisition.camera_fps)

    def _watch_loop(self) -> None:
        """Trips when a watched signal went quiet, or the camera's stream failed (its
        reader keeps what went wrong: the camera loop would see it only at its next
        batch, up to a camera period later). It looks when the first watched signal
        would be overdue, at once when the camera's stream fails or the loops are told
        to stop, and every watch period while nothing is watched (or after a trip)."""
        length = self.rig.length
        stream_fault = getattr(length, "stream_fault", None)

        def watch_once() -> None:
            if stream_fault is not None:
                self.watch.arrived("camera", length.newest_frame_s())
                if reason := stream_fault():
                    self.monitor.trip(f"camera: {reason}", "faulted")
            if reason := self.watch.overdue():
                self.monitor.trip(reason, "faulted")

        def fault_seen() -> bool:
            return stream_fault is not None and stream_fault() is not None

        def woken() -> bool:
            return self._stop_loops.is_set() or fault_seen()

        while not self._stop_loops.is_set() and self._read_once("watch", watch_once):
            wait_s = self.watch.next_due_s() - self.clock.now()
            if not 0 < wait_s < math.inf:
                wait_s = self.timing.watch_period_s  # nothing watched, or tripped
            # at least a microsecond: a due time a rounding short of the clock's
            # nanoseconds must not wake the loop at the same instant again
            wait_s = max(wait_s, 1e-6)
            self.clock.wait_for(self._stop_loops.is_set if fault_seen() else woken, wait_s)

    def _device_loop(
        self,
        device: str,
        period_s: float | None,
        read_once: Callable[[], None],
        rephase: Callable[[], int] | None = None,
    ) -> None:
        """Read one device every ``period_s`` (paced by deadlines, so a slow read does
        not stretch the period), or as fast as its reads return (``None``: a read that
        waits for the device); a device error is a fault of the run. When
        ``rephase()`` changes, read at once and count the periods from then."""
        start_s, k = self.clock.now(), 0
        token = rephase() if rephase is not None else None
        while not self._stop_loops.is_set():
            if not self._read_once(device, read_once):
                return
            if period_s is None:
                continue
            # deadlines on a fixed grid (start + k periods, no accumulated rounding); a
            # read that overran whole periods skips them rather than bunching up
            k = max(k + 1, math.floor((self.clock.now() - start_s) / period_s))
            wait_s = start_s + k * period_s - self.clock.now()
            if rephase is None:
                self.clock.sleep(wait_s)
            elif self.clock.wait_for(lambda seen=token: rephase() != seen, wait_s):
                token, start_s, k = rephase(), self.clock.now(), 0

    def _read_once(self, device: str, read_once: Callable[[], None]) -> bool:
        """One read of a loop; False when a device error faulted the run (the loop
        ends)."""
        try:
            read_once()
        except (LabrigError, OSError) as exc:
            self.monitor.fault(exc, device)
            return False
        except Exception as exc:
            # a loop that died quietly would leave its interlock blind: fault the run
            self.monitor.trip(f"{device}: internal error: {exc!r}", "faulted")
            raise
        return True

    # --- readings: judged, then recorded -------------------------------------------
    def _read_pressure(self) -> None:
        block = self.rig.pressure.read()
        if len(block):
            self.monitor.check_pressure(block)
        self._record_pressure(block)

    def _record_pressure(self, block: PressureBlock) -> None:
        if len(block):
            repetition = self.repetition
            self.writer.put(
                self.file.append_pressure,
                repetition,
                block.t_s,
                block.pressure_kpa,
                block.out_of_range,
            )
            force_n = getattr(block, "force_n", None)
            if force_n is not None:
                self.writer.put(self.file.append_force, repetition, block.t_s, force_n)
            self.watch.arrived("pressure", float(block.t_s[-1]))
        latest = self.latest
        with latest.lock:
            if len(block):
                latest.pressure_kpa = float(block.pressure_kpa[-1])
                latest.pressure_samples += len(block)
            latest.pressure_blocks += 1

    def _read_pump(self) -> None:
        with self.latest.lock:
            seq = self.motion_seq
        with self.volume_lock:
            status = self.rig.pump.status()
            volume_ml = self.monitor.specimen_volume_ml(status)
        self.monitor.check_pump(status, volume_ml)
        self.writer.put(
            self.file.append_pump,
            self.repetition,
            status.t_s,
            volume_ml,
            status.infused_ml,
            status.withdrawn_ml,
            status.state.value,
        )
        latest = self.latest
        with latest.lock:
            latest.volume_ml = volume_ml
            latest.pump_state = status.state
            latest.pump_t_s = status.t_s
            latest.pump_seq = seq

    def _read_length(self) -> None:
        sample = self.rig.length.read()
        if sample is not None and not self._stop_loops.is_set():
            # a frame that came after the loops were told to stop is not recorded
            self._record_lengths([sample])

    def _read_lengths(self, since_s: float, until_s: float = math.inf, rest=False) -> None:
        """Record the batch of frames measured since the last call (``read_new``: the
        frames taken one camera period before; ``rest``: every frame taken); frames from
        before this loop started (the camera streams on while acquisition pauses) are
        not recorded."""
        length = self.rig.length
        new = length.read_rest() if rest else length.read_new()
        samples = [s for s in new if since_s <= s.t_s <= until_s]
        if samples:
            self._record_lengths(samples)

    def _record_lengths(self, samples: list[LengthSample]) -> None:
        """A batch of frames judged by the markers-lost interlock, in order, then
        recorded into the run file (and the video), each frame in the repetition that
        was running when it was taken (a batch is recorded a camera period or two after
        its frames)."""
        for sample in samples:
            self._check_markers(sample)
        for repetition, group in itertools.groupby(samples, lambda s: self.repetition_at(s.t_s)):
            self._record_repetition_lengths(repetition, list(group))

    def _record_repetition_lengths(self, repetition: int, samples: list[LengthSample]) -> None:
        columns = np.array(
            [(s.t_s, s.length_mm, s.x1_px, s.y1_px, s.x2_px, s.y2_px) for s in samples]
        ).T
        ok = np.array([s.ok for s in samples])
        self.writer.put(self.file.append_length, repetition, *columns, ok)
        if self.video is not None:
            framed = [s for s in samples if s.image is not None]
            handed_before = self.video.n_frames
            try:
                self.video.add_many([s.image for s in framed])
            finally:  # the times of the frames handed to the video, also if it failed
                shown = self.video.n_frames - handed_before
                if shown:
                    times = np.array([s.t_s for s in framed[:shown]])
                    self.writer.put(self.file.append_video_frame, repetition, times)

    def _check_markers(self, sample: LengthSample) -> None:
        if sample.ok:
            self._marker_lost_since = None
            with self.latest.lock:
                self.latest.length_mm = sample.length_mm
        else:
            if self._marker_lost_since is None:
                self._marker_lost_since = sample.t_s
            lost_s = sample.t_s - self._marker_lost_since
            if lost_s >= self.timing.max_marker_loss_s:
                self.monitor.trip(
                    f"camera: markers lost for {lost_s:.1f} s (check the camera view "
                    "and the markers)",
                    "faulted",
                )
