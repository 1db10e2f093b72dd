"""The protocol runner: the main thread walks the protocol's steps, and every run ends
through one exit with the pump stopped and the operator told.

The runner only knows the device contracts (``labrig.rig.devices``) and the clock's
(``labrig.time.clock``): the same code drives the bench rig and the simulated one.
Around the steps it sets up the run's parts, each in a module of its own:

- the acquisition threads (``labrig.run.acquisition``): the DAQ stream, the pump poll,
  the camera and the signal watch on the rig's clock, each reading judged by the
  interlocks in the thread that read it, before it is queued for the file;
- the run file, written by a thread of its own (``labrig.run.background_writer``);
- the stop requests (``labrig.run.stop_signals``): Ctrl-C, SIGTERM, SIGHUP and the
  Windows console events all trip the interlock monitor like any fault.

The pump never starts unless a pressure sample came within the signal allowance, and
a camera whose scale is taken from its first frame is calibrated before anything
moves. A technician's step waits on a thread of its own, so a trip withdraws it.

Every way a run can end goes through one exit (``_shutdown``): the pump is sent a
stop and must confirm it (``labrig.run.pump_stop``), the loops are stopped, the
samples still in the DAQ's buffer and the frames still being tracked are recorded, and
the file is finalised with everything recorded so far and the run marked complete,
aborted or faulted with the reason, whatever fails on the way out. When an exchange
with the pump is cut short by a stop, the trip that sent the stop stays the reason.

Nothing is replayed: each infuse/withdraw step has an absolute target volume in the
specimen, and the pump is asked only for the difference between that target and the
volume it reports.
"""

from __future__ import annotations

import contextlib
import gc
import logging
import os
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from labrig.config.protocol import (
    HoldStep,
    InfuseStep,
    LoadedProtocol,
    PromptStep,
    Protocol,
    ReservoirStep,
    WithdrawStep,
    ZeroPressureStep,
    iter_plan,
    plan,
)
from labrig.errors import InputError, LabrigError
from labrig.recording.run_file_lock import check_run_name
from labrig.recording.run_writer import RunFileFailed, RunWriter
from labrig.recording.video import VideoRecorder
from labrig.rig.devices import PressureBlock, PumpState, Rig
from labrig.run.acquisition import Acquisition, Timing
from labrig.run.background_writer import BackgroundWriter
from labrig.run.interlocks import (
    Interlock,
    InterlockMonitor,
    PressureCeiling,
    PressureFrozen,
    PressureSignal,
    PumpStall,
    SpecimenPressure,
    VolumeCeiling,
)
from labrig.run.pump_stop import final_stop, unconfirmed_reason
from labrig.run.stop_signals import StopRequests

log = logging.getLogger(__name__)

MOVING = (PumpState.INFUSING, PumpState.WITHDRAWING)


def run_interlocks(protocol: Protocol) -> list[Interlock]:
    """The interlocks every reading of a run is judged by, in order (one line each);
    none needs the specimen's model."""
    # the specimen's before the signal's: suction on an emptied (leaking) specimen
    # reads below the sensor's range a moment after it shows in the means
    return [
        PressureCeiling(protocol.limits.max_pressure_kpa),
        SpecimenPressure(),
        PressureSignal(),
        PressureFrozen(),
        VolumeCeiling(protocol.limits.max_volume_ml),
        PumpStall(),
    ]


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
    # False when the pump never confirmed the run's last stop: it may still be moving
    stop_confirmed: bool = True


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
        self.monitor = InterlockMonitor(rig.pump, run_interlocks(self.protocol))
        self.stops = StopRequests(self._stop_requested)
        self._t_start = 0.0
        self._step_label = "starting"
        self._repetition_started = False
        self._last_progress_s = float("-inf")
        self.data_tap = data_tap  # sees every append to the run file (the live view)
        self.writer: BackgroundWriter | None = None
        self.acquisition: Acquisition | None = None
        self.video: VideoRecorder | None = None

    def _stop_requested(self, reason: str) -> None:
        """A signal's stop: tripped like a fault, and a paced clock (``--speed``) lets
        the stop and the file's end run at once, not at the pace's next instant."""
        stop_pacing = getattr(self.clock, "stop_pacing", None)
        if stop_pacing is not None:
            stop_pacing()
        self.monitor.trip(reason, "aborted")

    @property
    def shutdown_errors(self) -> list[str]:
        """What failed on the way out (the file was finalised all the same)."""
        return self.acquisition.shutdown_errors if self.acquisition else []

    # --- public --------------------------------------------------------------------
    def run(self) -> RunResult:
        """Run the protocol; always returns with the pump sent a stop and the file closed.
        A run file that cannot be made (another run writing it, an unusable path) is
        raised before anything moves, with the rig closed: nothing of it left running."""
        try:
            file = self._open_run_file()
        except BaseException:
            self.rig.close()
            raise
        if self._video_path() is not None:
            self.video = VideoRecorder(self._video_path(), self.protocol.acquisition.camera_fps)
        refused = ""
        # the main thread takes part in the clock's time for the whole run
        with self.stops.installed(), self.clock.participate(), _start_up_heap_frozen():
            self.writer = BackgroundWriter(
                file, self.clock, lambda why: self.monitor.trip(why, "faulted")
            )
            self.acquisition = Acquisition(
                self.rig,
                self.protocol,
                self.timing,
                self.monitor,
                self.writer,
                self.video,
                hurry=lambda: self.stops.hurry,
            )
            try:
                self._t_start = self.clock.now()
                self._execute()
            except _Refused as exc:
                refused = str(exc)
            except LabrigError as exc:
                # an exchange cut short by a trip's stop: the trip stays the reason
                self.monitor.fault(exc)
            except BaseException as exc:
                self.monitor.trip(f"internal error: {exc!r}", "faulted")
                raise
            finally:
                result = self._shutdown(refused)
                self.stops.finished.set()
        return result

    def _open_run_file(self) -> RunWriter:
        check_run_name(self.out_path)  # never one name for the file and its video
        video = self._video_path()
        if video is not None and os.path.lexists(video):  # the recorder would replace it
            raise InputError(
                f"{video}: a run's video is already there; a run never writes over one "
                "(labrig run --overwrite moves it aside first)"
            )
        return RunWriter(
            self.out_path,
            title=self.protocol.name,
            protocol_text=self.loaded.text,
            protocol_path=str(self.loaded.path),
            rig_config_text=self.rig.config_text,
            repetitions=max(1, self.plan.repetitions),
            with_length=self.rig.length is not None,
            camera_fps=self.protocol.acquisition.camera_fps,
            with_force=getattr(self.rig.pressure, "measures_force", False),
            with_events=self.rig.technician is not None,
            simulated_segments=self._simulated_segments(),
            specimen_model=self.protocol.specimen.model,
            tap=self.data_tap,
            video_file=self._video_path().name if self._video_path() else None,
            pump_identity=getattr(self.rig.pump, "run_record", None),
        )

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
            self.acquisition.start()
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
                message, connect = step.prompt.message, step.prompt.connect
                self._technician_step("prompt", 0.0, message)
                done = self._technician_acts(
                    lambda m=message, c=connect: self.rig.technician.prompt(m, c)
                )
                if done and connect is not None:
                    self._technician_step("connect", 0.0, connect)
            elif isinstance(step, ReservoirStep):
                volume_ml, duration_s = step.reservoir.volume_ml, step.reservoir.duration_s
                self._step_label = f"reservoir {volume_ml:g} mL"
                self._technician_step("reservoir", volume_ml, "")
                self._technician_acts(
                    lambda v=volume_ml, d=duration_s: self.rig.technician.reservoir(v, d)
                )
        if not self.monitor.tripped:
            self._leave_repetition("complete")

    def _technician_step(self, kind: str, volume_ml: float, message: str) -> None:
        if self.rig.technician is None:
            raise LabrigError(f"this rig has nobody to take a {kind} step")
        self.writer.put(self.writer.writer.append_event, self.clock.now(), kind, volume_ml, message)

    def _technician_acts(self, act: Callable[[], None]) -> bool:
        """The technician's part of a step, on a thread of the clock, while the main
        thread watches for a trip: a trip withdraws the step (the technician is told
        why, and the screen no longer asks for Enter). True once the step is done."""
        failure: list[BaseException] = []

        def acting() -> None:
            try:
                act()
            except BaseException as exc:  # raised here, in the main thread
                failure.append(exc)

        thread = self.clock.start_thread(acting, "technician")
        while not thread.done:
            if trip := self.monitor.tripped:
                self.rig.technician.withdraw(trip.reason)
                return False
            self.clock.wait_for(
                lambda: thread.done or self.monitor.tripped is not None,
                self.timing.progress_period_s,
            )
            self._report_progress()
        if failure:
            raise failure[0]
        return True

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
            self.writer.put(
                self.writer.writer.append_segment_volumes, t_s, plant.segment_volumes_ml_at(t_s)
            )

    def _check_start(self, block: PressureBlock | None) -> None:
        status = self.rig.pump.status()
        reason = self.monitor.check_start(status, block)
        if reason:
            raise _Refused(f"refusing to start: {reason}")

    def _zero(self, duration_s: float) -> None:
        self._step_label = "zero pressure"
        was_acquiring = self.acquisition.acquiring
        if was_acquiring:
            self.acquisition.stop()
        offset_kpa = self.rig.pressure.zero(duration_s)
        self.writer.put(self.writer.writer.set_zero_offset, offset_kpa)
        if was_acquiring:
            self.acquisition.start()

    def _flow(self, direction: int, rate_ml_min: float, target_ml: float) -> None:
        pump = self.rig.pump
        with self.acquisition.volume_lock:
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
        seq = self.acquisition.start_motion()
        expected_s = 60.0 * remaining_ml / rate_ml_min
        deadline_s = self.clock.now() + 1.2 * expected_s + self.timing.target_grace_s
        if self._wait_until_pump_stops(seq, deadline_s):
            self._check_arrival(target_ml)

    def _pressure_is_live(self) -> bool:
        """The pump starts only on a pressure signal that is live now: a sample within
        the signal allowance (the interlocks have judged every sample as it came)."""
        quiet_s = self.acquisition.watch.quiet_s("pressure")
        if quiet_s <= self.timing.signal_timeout_s:
            return True
        self.monitor.trip(
            f"refusing to start the pump: pressure: no sample for {quiet_s:.2f} s", "faulted"
        )
        return False

    def _wait_until_pump_stops(self, seq: int, deadline_s: float) -> bool:
        """True once a status newer than the run command shows the motor stopped."""
        latest = self.acquisition.latest

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
        with self.acquisition.volume_lock:
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
        acquisition = self.acquisition
        if repetition == acquisition.repetition and self._repetition_started:
            return
        if self._repetition_started:
            self._leave_repetition("complete")
        acquisition.repetition = repetition
        self._repetition_started = True
        acquisition.repetition_starts.append((self.clock.now(), repetition))
        self.writer.put(
            self.writer.writer.set_repetition_status,
            repetition,
            "running",
            t_start_s=self.clock.now(),
        )

    def _leave_repetition(self, status: str, reason: str = "") -> None:
        if self._repetition_started:
            self.writer.put(
                self.writer.writer.set_repetition_status,
                self.acquisition.repetition,
                status,
                reason,
                t_end_s=self.clock.now(),
            )
            self._repetition_started = False

    # --- progress and the end ------------------------------------------------------
    def _report_progress(self) -> None:
        if self.on_progress is None:
            return
        now = self.clock.now()
        if now - self._last_progress_s < self.timing.progress_period_s:
            return
        self._last_progress_s = now
        latest = self.acquisition.latest
        elapsed = now - self._t_start
        with latest.lock:
            snapshot = Progress(
                step=self._step_label,
                repetition=self.acquisition.repetition,
                repetitions=self.plan.repetitions,
                volume_ml=latest.volume_ml,
                pressure_kpa=latest.pressure_kpa,
                length_mm=latest.length_mm,
                elapsed_s=elapsed,
                remaining_s=max(0.0, self.plan.duration_s - elapsed),
            )
        try:
            self.on_progress(snapshot)
        except OSError as exc:
            # the terminal is gone (SSH closed: SIGHUP is on its way): the run goes on
            # to its stop without a display
            log.warning("progress display stopped: %s", exc)
            self.on_progress = None

    def _shutdown(self, refused: str) -> RunResult:
        """The one exit: pump stopped first, loops stopped, file finalised. The status
        is the first trip's (a refusal's, or complete); a stop the pump did not confirm
        faults the run, whatever stopped it."""
        trip = self.monitor.tripped
        if trip is not None:
            status, reason = trip.kind, trip.reason
        elif refused:
            status, reason = "aborted", refused
        else:
            status, reason = "complete", ""
        stop_problem = final_stop(self.rig.pump)
        if stop_problem is not None:
            status, reason = "faulted", unconfirmed_reason(stop_problem, reason)
        elif trip is not None and trip.reason_if_stopped is not None:
            reason = trip.reason_if_stopped
        try:
            self.acquisition.stop()
            if self.rig.length is not None:
                self.writer.put(self.writer.writer.set_measured_fps, self.rig.length.measured_fps)
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
                if self.writer.writer.simulated_segments:
                    self._record_simulation(self.clock.now())
                try:
                    self.writer.close(
                        status,
                        reason,
                        self.timing.writer_drain_s,
                        lambda: self.stops.hurry,
                        pump_stop_confirmed=stop_problem is None,
                    )
                except RunFileFailed as exc:  # a full disk, the file removed: never complete
                    why = f"run file: {exc}"
                    status, reason = "faulted", why if not reason or why in reason else reason
            finally:
                self.rig.close()
        return RunResult(self.out_path, status, reason, stop_problem is None)


class _Refused(LabrigError):
    """The run was refused before anything moved."""


@contextlib.contextmanager
def _start_up_heap_frozen():
    """The objects made before the run (the imported modules, the model's tables: some
    hundred thousand) moved out of the garbage collector's reach while it runs, and
    back after. They live to the end anyway, and every full collection the run's
    allocations trigger would walk them all, holding the interpreter's lock while the
    acquisition threads wait (the simulated demo: 1.4 s of its 8.6 s under load).
    Unfrozen after the run: cycles made before it can still be collected later in a
    process that goes on (a notebook, the test suite)."""
    gc.freeze()
    try:
        yield
    finally:
        gc.unfreeze()
