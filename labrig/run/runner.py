"""The protocol runner: pump control and acquisition at once, interlocks always on.

The runner only knows the device contracts (``labrig.rig.devices``) and the clock's
(``labrig.time.clock``): the same code drives the bench rig and the simulated one. Three
acquisition loops run in their own threads on the rig's clock — the DAQ stream, the
pump poll, the camera — and each sample is appended to the run file as it arrives,
timestamped by the device on the shared clock. Every wait goes through the clock
(sleeps, conditions, the loops' start and end), so on the simulated rig's virtual
clock no decision depends on how fast the host is: time moves only while all wait.
The interlock monitor is evaluated inside those loops, so a busy main loop cannot delay
a stop; a fourth loop watches that the pressure samples and the camera's frames keep
coming (``labrig.run.signal_watch``), since a dead device sends nothing to trip on. The
pump never starts unless a pressure sample came within that allowance, and a camera
whose scale is taken from its first frame is calibrated before anything moves. The
main thread walks the protocol's steps.

Every way a run can end goes through one exit: the pump is stopped first, the loops
are stopped, the samples still in the DAQ's buffer and the frames still being tracked
are recorded, and the file is finalised with everything recorded so far and the run
marked complete, aborted or faulted with the reason, whatever fails on the way out.
The first Ctrl-C stops safely like any interlock; the second stops now (the pump is
still sent a stop).

Nothing is replayed: each infuse/withdraw step has an absolute target volume in the
specimen, and the pump is asked only for the difference between that target and the
volume it reports.
"""

from __future__ import annotations

import bisect
import contextlib
import itertools
import math
import os
import signal
import threading
from collections.abc import Callable
from dataclasses import dataclass, field
from operator import itemgetter
from pathlib import Path

import numpy as np

from labrig.config.protocol import (
    HoldStep,
    InfuseStep,
    LoadedProtocol,
    PromptStep,
    ReservoirStep,
    WithdrawStep,
    ZeroPressureStep,
    iter_plan,
    plan,
)
from labrig.errors import LabrigError
from labrig.recording.run_writer import RunWriter
from labrig.recording.video import VideoRecorder
from labrig.rig.devices import (
    LengthSample,
    LengthSource,
    PressureBlock,
    PressureSource,
    Pump,
    PumpState,
)
from labrig.run.interlocks import (
    InterlockMonitor,
    PressureCeiling,
    PressureSignal,
    PressureStuck,
    PumpStall,
    VolumeCeiling,
)
from labrig.run.signal_watch import SignalWatch
from labrig.time.clock import Clock, ClockThread

MOVING = (PumpState.INFUSING, PumpState.WITHDRAWING)


@dataclass
class Rig:
    """The devices of one run and the clock they share."""

    clock: Clock
    pump: Pump
    pressure: PressureSource
    length: LengthSource | None
    config_text: str
    close: Callable[[], None] = lambda: None
    # The simulated specimen and emulators behind the drivers, when simulated: the
    # truth that tests and benchmarks compare the recorded data with.
    simulation: object | None = None
    # who answers the protocol's prompts and pushes the reservoir (labrig.run.technician)
    technician: object | None = None


@dataclass(frozen=True)
class Progress:
    """A snapshot for the live display."""

    step: str
    repetition: int
    repetitions: int
    volume_ml: float
    pressure_kpa: float
    length_mm: float
    elapsed_s: float
    remaining_s: float


@dataclass(frozen=True)
class RunResult:
    path: Path
    status: str
    reason: str


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
    # periods if longer) is a dead device, as is a pressure this long at one number
    signal_timeout_s: float = 0.5
    watch_period_s: float = 0.1


@dataclass
class _Latest:
    pressure_kpa: float = float("nan")
    length_mm: float = float("nan")
    volume_ml: float = 0.0
    pump_state: PumpState = PumpState.IDLE
    pump_t_s: float = float("-inf")
    pump_seq: int = -1
    pressure_blocks: int = 0
    pressure_samples: int = 0
    lock: threading.Lock = field(default_factory=threading.Lock)


class Runner:
    """Run one validated protocol on one rig into one HDF5 file."""

    def __init__(
        self,
        loaded: LoadedProtocol,
        rig: Rig,
        out_path: str | Path,
        *,
        on_progress: Callable[[Progress], None] | None = None,
        timing: Timing | None = None,
        data_tap: Callable[[int, str, dict], None] | None = None,
    ) -> None:
        self.loaded = loaded
        self.protocol = loaded.protocol
        self.rig = rig
        self.clock = rig.clock
        self.out_path = Path(out_path)
        self.on_progress = on_progress
        self.timing = timing or Timing()
        self.plan = plan(self.protocol)
        self.monitor = InterlockMonitor(
            rig.pump,
            [
                PressureCeiling(self.protocol.limits.max_pressure_kpa),
                PressureSignal(),
                PressureStuck(self.timing.signal_timeout_s),
                VolumeCeiling(self.protocol.limits.max_volume_ml),
                PumpStall(),
            ],
        )
        self.watch = SignalWatch(rig.clock)
        self.latest = _Latest()
        self._repetition = 1
        # (start time, repetition) of each repetition entered, in order: frames are
        # recorded after the fact, into the repetition of their time
        self._repetition_starts: list[tuple[float, int]] = []
        self._volume_lock = threading.Lock()
        self._stop_loops = threading.Event()
        self._stopped_at_s = math.inf  # when the loops were last told to stop
        self._threads: list[ClockThread] = []
        self._acquiring = False
        self._t_start = 0.0
        self._step_label = "starting"
        self._repetition_started = False
        self._motion_seq = 0
        self._shutting_down = False
        self._interrupts = 0
        self._hurry = False
        self._marker_lost_since: float | None = None
        self._last_progress_s = float("-inf")
        self.shutdown_errors: list[str] = []
        self.writer: RunWriter | None = None
        self.data_tap = data_tap  # sees every append to the run file (the live view)
        self.video: VideoRecorder | None = None

    # --- public --------------------------------------------------------------------
    def run(self) -> RunResult:
        """Run the protocol; always returns with the pump stopped and the file closed."""
        self.writer = RunWriter(
            self.out_path,
            title=self.protocol.name,
            protocol_text=self.loaded.text,
            protocol_path=str(self.loaded.path),
            rig_config_text=self.rig.config_text,
            repetitions=max(1, self.plan.repetitions),
            with_length=self.rig.length is not None,
            with_force=getattr(self.rig.pressure, "measures_force", False),
            with_events=self.rig.technician is not None,
            simulated_segments=self._simulated_segments(),
            tap=self.data_tap,
            video_file=self._video_path().name if self._video_path() else None,
        )
        if self._video_path() is not None:
            self.video = VideoRecorder(self._video_path(), self.protocol.acquisition.camera_fps)
        restore_sigint = self._install_sigint()
        status, reason = "faulted", "the run did not finish"
        # the main thread takes part in the clock's time for the whole run
        with self.clock.participate():
            try:
                self._t_start = self.clock.now()
                self._execute()
                trip = self.monitor.tripped
                status, reason = (trip.kind, trip.reason) if trip else ("complete", "")
            except _StopNow:
                status, reason = "aborted", "stopped now by the operator (second Ctrl-C)"
            except _Refused as exc:
                status, reason = "aborted", str(exc)
            except LabrigError as exc:
                self.monitor.trip(str(exc), "faulted")
                status, reason = "faulted", str(exc)
            except BaseException as exc:
                self.monitor.trip(f"internal error: {exc!r}", "faulted")
                status, reason = "faulted", f"internal error: {exc!r}"
                raise
            finally:
                self._shutdown(status, reason)
                restore_sigint()
        return RunResult(self.out_path, status, reason)

    def _video_path(self) -> Path | None:
        """RUN.avi beside RUN.h5, when the protocol asks for a video and has a camera."""
        if not self.protocol.acquisition.video or self.rig.length is None:
            return None
        return self.out_path.with_suffix(".avi")

    # --- steps ---------------------------------------------------------------------
    def _execute(self) -> None:
        self._check_start(None)
        target_ml = 0.0
        for _, step, repetition in iter_plan(self.protocol.steps):
            if self.monitor.tripped:
                return
            if isinstance(step, ZeroPressureStep):
                self._zero(step.zero_pressure.duration_s)
                continue
            self._ensure_acquiring()
            self._enter_repetition(repetition)
            if isinstance(step, InfuseStep):
                target_ml += step.infuse.volume_ml
                self._step_label = f"infuse {step.infuse.volume_ml:g} mL"
                self._flow(+1, step.infuse.rate_ml_min, target_ml)
            elif isinstance(step, WithdrawStep):
                target_ml -= step.withdraw.volume_ml
                self._step_label = f"withdraw {step.withdraw.volume_ml:g} mL"
                self._flow(-1, step.withdraw.rate_ml_min, target_ml)
            elif isinstance(step, HoldStep):
                self._step_label = f"hold {step.hold.seconds:g} s"
                self._hold(step.hold.seconds)
            elif isinstance(step, PromptStep):
                self._step_label = "waiting for the technician"
                self._technician_step("prompt", 0.0, step.prompt.message)
                self.rig.technician.prompt(step.prompt.message, step.prompt.connect)
                if step.prompt.connect is not None:
                    self._technician_step("connect", 0.0, step.prompt.connect)
            elif isinstance(step, ReservoirStep):
                volume_ml = step.reservoir.volume_ml
                self._step_label = f"reservoir {volume_ml:g} mL"
                self._technician_step("reservoir", volume_ml, "")
                self.rig.technician.reservoir(volume_ml, step.reservoir.duration_s)
        if not self.monitor.tripped:
            self._leave_repetition("complete")

    def _technician_step(self, kind: str, volume_ml: float, message: str) -> None:
        if self.rig.technician is None:
            raise LabrigError(f"this rig has nobody to take a {kind} step")
        self.writer.append_event(self.clock.now(), kind, volume_ml, message)

    def _simulated_segments(self) -> int:
        """How many segment volumes the simulated plant can tell (0: none to record)."""
        plant = getattr(self.rig.simulation, "plant", None)
        return plant.n if hasattr(plant, "segment_volumes_ml_at") else 0

    def _record_simulation(self, t_end_s: float) -> None:
        """The simulated segments' volumes over the run, at 100 Hz (the truth a real rig
        cannot measure: how much fluid flowed between the segments)."""
        plant = self.rig.simulation.plant
        t_s = np.arange(self._t_start, t_end_s, 0.01)
        if len(t_s):
            self.writer.append_segment_volumes(t_s, plant.segment_volumes_ml_at(t_s))

    def _check_start(self, block: PressureBlock | None) -> None:
        status = self.rig.pump.status()
        reason = self.monitor.check_start(status, block)
        if reason:
            raise _Refused(f"refusing to start: {reason}")

    def _zero(self, duration_s: float) -> None:
        self._step_label = "zero pressure"
        was_acquiring = self._acquiring
        if was_acquiring:
            self._stop_acquisition()
        offset_kpa = self.rig.pressure.zero(duration_s)
        self.writer.set_zero_offset(offset_kpa)
        if was_acquiring:
            self._ensure_acquiring()

    def _flow(self, direction: int, rate_ml_min: float, target_ml: float) -> None:
        pump = self.rig.pump
        with self._volume_lock:
            status = pump.status()
            current_ml = self.monitor.specimen_volume_ml(status)
            remaining_ml = direction * (target_ml - current_ml)
            if remaining_ml <= 1e-3:
                return
            # counters are cleared per step so the pump's target needs no firmware-
            # specific arithmetic; the volume already moved is carried in the offset
            self.monitor.volume_offset_ml = current_ml
            pump.clear_volumes()
        if direction > 0:
            pump.set_infuse_rate(rate_ml_min)
        else:
            pump.set_withdraw_rate(rate_ml_min)
        pump.set_target_volume(remaining_ml)
        if self.monitor.tripped or not self._pressure_is_live():
            return
        pump.infuse() if direction > 0 else pump.withdraw()
        with self.latest.lock:
            # only a status requested after this point may say the motion has ended
            self._motion_seq += 1
            seq = self._motion_seq
        expected_s = 60.0 * remaining_ml / rate_ml_min
        deadline_s = self.clock.now() + 1.2 * expected_s + self.timing.target_grace_s
        if self._wait_until_pump_stops(seq, deadline_s):
            self._check_arrival(target_ml)

    def _pressure_is_live(self) -> bool:
        """The pump starts only on a pressure signal that is live now: a sample within
        the signal allowance (the interlocks have judged every sample as it came)."""
        quiet_s = self.watch.quiet_s("pressure")
        if quiet_s <= self.timing.signal_timeout_s:
            return True
        self.monitor.trip(
            f"refusing to start the pump: no pressure sample for {quiet_s:.2f} s", "faulted"
        )
        return False

    def _wait_until_pump_stops(self, seq: int, deadline_s: float) -> bool:
        """True once a status newer than the run command shows the motor stopped."""
        latest = self.latest

        def stopped() -> bool:
            return latest.pump_seq >= seq and latest.pump_state not in MOVING

        while not self.monitor.tripped:
            if stopped():
                return True
            if self.clock.now() > deadline_s:
                self.monitor.trip("the pump did not reach its target volume in time", "faulted")
                return False
            wait_s = min(self.timing.progress_period_s, deadline_s - self.clock.now())
            self.clock.wait_for(lambda: stopped() or self.monitor.tripped is not None, wait_s)
            self._report_progress()
        return False

    def _check_arrival(self, target_ml: float) -> None:
        """A pump that stopped short of its target (stopped at the pump, a lost step)
        is a fault: the following steps would start from the wrong volume."""
        with self._volume_lock:
            volume_ml = self.monitor.specimen_volume_ml(self.rig.pump.status())
        if abs(volume_ml - target_ml) > 0.05 + 0.01 * abs(target_ml):
            self.monitor.trip(
                f"the pump stopped at {volume_ml:.3f} mL instead of {target_ml:.3f} mL",
                "faulted",
            )

    def _hold(self, seconds: float) -> None:
        end_s = self.clock.now() + seconds
        while not self.monitor.tripped and self.clock.now() < end_s:
            self.clock.sleep(min(self.timing.pump_period_s, max(0.0, end_s - self.clock.now())))
            self._report_progress()

    # --- repetitions ---------------------------------------------------------------
    def _enter_repetition(self, repetition: int) -> None:
        if repetition == self._repetition and self._repetition_started:
            return
        if self._repetition_started:
            self._leave_repetition("complete")
        self._repetition = repetition
        self._repetition_started = True
        self._repetition_starts.append((self.clock.now(), repetition))
        self.writer.set_repetition_status(repetition, "running", t_start_s=self.clock.now())

    def _leave_repetition(self, status: str, reason: str = "") -> None:
        if self._repetition_started:
            self.writer.set_repetition_status(
                self._repetition, status, reason, t_end_s=self.clock.now()
            )
            self._repetition_started = False

    # --- acquisition loops ---------------------------------------------------------
    def _ensure_acquiring(self) -> None:
        if self._acquiring:
            return
        self._stop_loops.clear()
        camera = self.rig.length is not None and self.protocol.acquisition.camera_fps > 0
        if camera and hasattr(self.rig.length, "calibrate"):
            self.rig.length.calibrate()  # a scale taken from a frame, before anything moves
        self.rig.pressure.start(self.protocol.acquisition.pressure_rate_hz)
        self._acquiring = True
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

    def _stop_acquisition(self) -> None:
        self._stopped_at_s = self.clock.now()
        self._stop_loops.set()
        threads = self._threads
        # a second Ctrl-C waits for nothing: the loops stop at their next wake-up
        self.clock.wait_for(
            lambda: all(thread.done for thread in threads),
            timeout_s=0.0 if self._hurry else self.timing.loop_exit_s,
        )
        self._threads = []
        self.watch.forget()
        if self._acquiring:
            self._acquiring = False
            try:
                self._record_pressure(self.rig.pressure.read())  # what the buffer still holds
            except (LabrigError, OSError) as exc:
                self.shutdown_errors.append(f"pressure read at stop: {exc}")
            try:
                self.rig.pressure.stop()
            except (LabrigError, OSError) as exc:
                # keep going: the file must still be finalised; the error is reported
                self.shutdown_errors.append(f"pressure stop: {exc}")

    def _current_repetition(self) -> int:
        return self._repetition

    def _repetition_at(self, t_s: float) -> int:
        """The repetition that was running at ``t_s`` (the first one before any)."""
        if not self._repetition_starts:
            return self._repetition
        i = bisect.bisect_right(self._repetition_starts, t_s, key=itemgetter(0))
        return self._repetition_starts[max(i - 1, 0)][1]

    def _pressure_loop(self) -> None:
        self._device_loop("pressure", self.timing.pressure_period_s, self._read_pressure)

    def _pump_loop(self) -> None:
        # polled at once when a motion starts, then every period from there: identical
        # steps are seen to end after identical times
        self._device_loop(
            "pump", self.timing.pump_period_s, self._read_pump, rephase=lambda: self._motion_seq
        )

    def _camera_loop(self) -> None:
        # a live camera's reader thread measures every frame it streams (at the
        # protocol's camera_fps) and the loop records them in batches; a video file
        # standing in for the camera is read and measured at camera_fps
        if getattr(self.rig.length, "waits_for_frames", False):
            since_s = self.clock.now()
            self.watch.expect("camera", self._frame_allowance_s())
            self._device_loop(
                "camera", self.timing.camera_period_s, lambda: self._read_lengths(since_s)
            )
            if not self._hurry:
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
        batch, up to a camera period later)."""
        length = self.rig.length
        stream_fault = getattr(length, "stream_fault", None)

        def watch_once() -> None:
            if stream_fault is not None:
                self.watch.arrived("camera", length.newest_frame_s())
                if reason := stream_fault():
                    self.monitor.trip(f"camera: {reason}", "faulted")
            if reason := self.watch.overdue():
                self.monitor.trip(reason, "faulted")

        self._device_loop("watch", self.timing.watch_period_s, watch_once)

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
            try:
                read_once()
            except (LabrigError, OSError) as exc:
                self.monitor.trip(f"{device}: {exc}", "faulted")
                return
            except Exception as exc:
                # a loop that died quietly would leave its interlock blind: fault the run
                self.monitor.trip(f"{device}: internal error: {exc!r}", "faulted")
                raise
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

    def _read_pressure(self) -> None:
        block = self.rig.pressure.read()
        self._record_pressure(block)
        if len(block):
            self.monitor.check_pressure(block)

    def _record_pressure(self, block: PressureBlock) -> None:
        if len(block):
            self.writer.append_pressure(
                self._current_repetition(), block.t_s, block.pressure_kpa, block.out_of_range
            )
            force_n = getattr(block, "force_n", None)
            if force_n is not None:
                self.writer.append_force(self._current_repetition(), block.t_s, force_n)
            self.watch.arrived("pressure", float(block.t_s[-1]))
        latest = self.latest
        with latest.lock:
            if len(block):
                latest.pressure_kpa = float(block.pressure_kpa[-1])
                latest.pressure_samples += len(block)
            latest.pressure_blocks += 1

    def _read_pump(self) -> None:
        with self.latest.lock:
            seq = self._motion_seq
        with self._volume_lock:
            status = self.rig.pump.status()
            volume_ml = self.monitor.specimen_volume_ml(status)
        self.writer.append_pump(
            self._current_repetition(),
            status.t_s,
            volume_ml,
            status.infused_ml,
            status.withdrawn_ml,
            status.state.value,
        )
        self.monitor.check_pump(status, volume_ml)
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
        """A batch of frames into the run file (and the video), each frame in the
        repetition that was running when it was taken (a batch is recorded a camera
        period or two after its frames), then the markers-lost interlock over them in
        order."""
        for repetition, group in itertools.groupby(samples, lambda s: self._repetition_at(s.t_s)):
            self._record_repetition_lengths(repetition, list(group))
        for sample in samples:
            self._check_markers(sample)

    def _record_repetition_lengths(self, repetition: int, samples: list[LengthSample]) -> None:
        columns = np.array(
            [(s.t_s, s.length_mm, s.x1_px, s.y1_px, s.x2_px, s.y2_px) for s in samples]
        ).T
        self.writer.append_length(repetition, *columns, np.array([s.ok for s in samples]))
        if self.video is not None:
            framed = [s for s in samples if s.image is not None]
            handed_before = self.video.n_frames
            try:
                self.video.add_many([s.image for s in framed])
            finally:  # the times of the frames handed to the video, also if it failed
                shown = self.video.n_frames - handed_before
                if shown:
                    times = np.array([s.t_s for s in framed[:shown]])
                    self.writer.append_video_frame(repetition, times)

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

    # --- time, progress, signals -----------------------------------------------------
    def _report_progress(self) -> None:
        if self.on_progress is None:
            return
        now = self.clock.now()
        if now - self._last_progress_s < self.timing.progress_period_s:
            return
        self._last_progress_s = now
        latest = self.latest
        elapsed = now - self._t_start
        with latest.lock:
            snapshot = Progress(
                step=self._step_label,
                repetition=self._repetition,
                repetitions=self.plan.repetitions,
                volume_ml=latest.volume_ml,
                pressure_kpa=latest.pressure_kpa,
                length_mm=latest.length_mm,
                elapsed_s=elapsed,
                remaining_s=max(0.0, self.plan.duration_s - elapsed),
            )
        self.on_progress(snapshot)

    def _install_sigint(self) -> Callable[[], None]:
        """First Ctrl-C: stop safely, like any interlock. Second: stop now — leave the
        step loop at once and do not wait for the acquisition threads (the pump is
        still sent a stop). The handler does no I/O itself: it runs in the main thread,
        which may be inside a driver call holding the port's lock."""
        if threading.current_thread() is not threading.main_thread():
            return lambda: None
        previous = signal.getsignal(signal.SIGINT)

        def handler(signum, frame):
            if not self.clock.interruptible():
                # inside the virtual clock's hand-over: ask again in a moment (the
                # clock's docstring says why it must not be cut short)
                threading.Timer(0.001, os.kill, (os.getpid(), signal.SIGINT)).start()
                return
            self._interrupts += 1
            if self._interrupts == 1:
                threading.Thread(
                    target=self.monitor.trip,
                    args=("stopped by the operator (Ctrl-C)", "aborted"),
                    name="ctrl-c",
                    daemon=True,
                ).start()
                return
            self._hurry = True
            if not self._shutting_down:
                raise _StopNow()

        signal.signal(signal.SIGINT, handler)
        return lambda: signal.signal(signal.SIGINT, previous)

    def _shutdown(self, status: str, reason: str) -> None:
        """The one exit: pump stopped first, loops stopped, file finalised. Once here,
        a further Ctrl-C changes nothing: this is already the fastest way out."""
        self._shutting_down = True
        try:
            self.rig.pump.stop()
        except (LabrigError, OSError) as exc:
            if not reason:
                status, reason = "faulted", f"pump stop failed: {exc}"
        try:
            self._stop_acquisition()
            if self.video is not None:
                self.video.close()
                if self.video.error is not None and not reason:
                    status, reason = "faulted", f"video: {self.video.error}"
        except Exception as exc:
            # whatever broke on the way out, the file is finalised with what it holds
            self.shutdown_errors.append(f"shutdown: {exc!r}")
            if not reason:
                status, reason = "faulted", f"shutdown failed: {exc!r}"
        finally:
            try:
                if self._repetition_started:
                    self._leave_repetition(status, reason)
                if self.writer.simulated_segments:
                    self._record_simulation(self.clock.now())
                self.writer.finalise(status, reason)
            finally:
                self.rig.close()


class _StopNow(BaseException):
    """The second Ctrl-C: leave at once (the shutdown still stops the pump)."""


class _Refused(LabrigError):
    """The run was refused before anything moved."""
