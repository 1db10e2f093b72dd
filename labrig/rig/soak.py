"""The fault soak: many simulated runs, each ended by one fault at a random rig time,
each checked for what a technician counts on.

Every run infuses and withdraws on the simulated rig (virtual time: a run of 22 s of
rig time takes a fraction of that on the host) while one of ``FAULTS`` strikes at a
time drawn from the seed: a sensor wire cut (before the run or during it), a frozen
sensor, a specimen that bursts, a DAQ that stalls or is unplugged, a pump whose reply
line dies mid-reply or as its stop arrives, a pump that drops off USB and
re-enumerates, a camera whose frames stop or whose clock jumps, and the endings a person
or the system gives: Ctrl-C while the run is paced (``--speed``) or holding, SIGTERM,
SIGHUP; and the pump as a shared bench leaves it: running when the run connects, in a
Quick Start variant that refuses a direction, another pump answering behind its
re-found by-id link, confirmations slower than half a second (each ended by a fault of
its own, and each with a check of its own: the pump stopped and said so, the mode
loaded, no stop sent to the other pump, the stop confirmed). Every run's camera is slow
to start (its first frame 0.3-1 s after the stream starts, as a UVC webcam's), and every
run's disk turns slow as the fault strikes (each write to the run file then takes
``SLOW_WRITE_S``). A run is safe when
- the emulated plunger stood still from at most ``MAX_STOP_S`` of rig time after the
  fault on (``IN_RANGE_DEATH_STOP_S`` for a dead sensor that reads in range; the
  firmware's own record of the volume, not the driver's), or the run says first of
  all that the pump's stop was not confirmed (the operator is told);
- the run file is finalised (readable, not "running") with the fault's status and a
  reason that names the fault;
- no pressure sample and no camera frame from before the fault is missing (the
  samples are evenly spaced from the first to the fault, the frames up to one
  allowance before it).
The process's resident memory is read after every run: it must stay flat, since a
leak of threads, pseudo-terminals or tracker processes would show there first.
"""

from __future__ import annotations

import contextlib
import gc
import os
import random
import resource
import signal
import tempfile
import time
from collections import Counter
from collections.abc import Callable
from dataclasses import asdict, dataclass, replace
from pathlib import Path

import numpy as np

from labrig.config.protocol import load_protocol
from labrig.config.rig_file import PressureConfig, PumpConfig, RigConfig, SimConfig
from labrig.recording.run_reader import open_run, read_log
from labrig.rig.devices import Rig
from labrig.rig.simulated import build_simulated_rig
from labrig.run.pump_stop import PUMP_STOP_NOT_CONFIRMED
from labrig.run.runner import Runner

# the plunger must stand still this long (rig seconds) after the fault at the latest
MAX_STOP_S = 1.0
# a pump whose replies stopped costs this many host seconds per unanswered exchange
# (virtual time stands still meanwhile); the runs' default 10 s would make the soak
# wait minutes for nothing
REPLY_TIMEOUT_S = 1.0
# the fault strikes between these rig times after the run starts: after the zeroing,
# the first samples and the camera's first frame (which comes up to 1 s after the
# stream starts), before the protocol's end
FAULT_WINDOW_S = (2.5, 20.0)
# memory is flat when the last run's resident size exceeds the one after the warm-up
# runs (the first tenth, at least 5) by less than this
RSS_GROWTH_LIMIT_MB = 32.0
PRESSURE_RATE_HZ = 1000.0
CAMERA_FPS = 10.0
PROTOCOL = f"""\
name: fault soak
specimen: {{segments: [B46-T20, B46-T22], fittings_length_mm: 10}}
rig: sim
limits: {{max_pressure_kpa: 95, max_volume_ml: 40}}
acquisition: {{pressure_rate_hz: {PRESSURE_RATE_HZ:g}, camera_fps: {CAMERA_FPS:g}}}
steps:
  - zero_pressure: {{duration_s: 0.5}}
  - infuse: {{rate_ml_min: 60, volume_ml: 10}}
  - hold: {{seconds: 1}}
  - withdraw: {{rate_ml_min: 60, volume_ml: 10}}
"""


def _daq(rig: Rig):
    return rig.simulation.daq_tasks[-1]  # the task acquiring now


@dataclass(frozen=True)
class Fault:
    """How to inflict one fault on a simulated rig, and what its run's reason says.

    ``status``: how the run must end; ``unconfirmed``: the fault leaves the pump's stop
    unconfirmed (the run must say so first); ``speed``: the run paced to this many
    times real time (a signal comes in host time); ``window_s``: the rig times the
    fault strikes between, when not ``FAULT_WINDOW_S``; ``stop_s``: how long after the
    fault the plunger may still move; ``before_connect``: the state the emulated pump
    is left in before the driver connects; ``check``: what else the run must show (a
    list of problems, empty when it does), from the rig and the run file's path."""

    inflict: Callable[[Rig, random.Random], None]
    reason: str
    status: str = "faulted"
    unconfirmed: bool = False
    speed: float | None = None
    window_s: tuple[float, float] | None = None
    stop_s: float = MAX_STOP_S
    before_connect: Callable[[object, random.Random], None] | None = None
    check: Callable[[Rig, Path], list[str]] | None = None
    before_recording: bool = False  # strikes before the run records anything


# a signal's run is paced: the handler runs in host time, and an unpaced rig would
# run on meanwhile at many times real time
SIGNAL_SPEED = 5.0
# (a signal's window is short, so its paced runs cost little wall time)
SIGNAL_WINDOW_S = (2.5, 6.0)
# every run's disk turns slow as its fault strikes: this long (rig seconds) for each
# write to the run file (a USB stick, a network share), so no stop may wait for it
SLOW_WRITE_S = 0.5
# every run's camera delivers its first frame this long after the stream starts
CAMERA_FIRST_FRAME_S = (0.3, 1.0)
# A frozen sensor still reads in range: it strikes while the soak specimen is infused
# (about 1-3 mL at 60 mL/min) and is seen once its one number has lasted 0.3 s after a
# dithering second; the pump may run on for that and the stop
IN_RANGE_DEATH_WINDOW_S = (2.5, 3.5)
IN_RANGE_DEATH_STOP_S = 1.5


def _send(signum: int) -> Callable[[Rig, random.Random], None]:
    return lambda rig, rng: os.kill(os.getpid(), signum)


def _ctrl_c_in_the_hold(rig: Rig, rng: random.Random) -> None:
    """Ctrl-C once the infusion has ended (the protocol holds for 1 s)."""
    emulator = rig.simulation.emulator
    rig.clock.wait_for(lambda: emulator.net_volume_ml(rig.clock.now()) >= 9.999, 60.0)
    rig.clock.sleep(rng.uniform(0.1, 0.8))
    os.kill(os.getpid(), signal.SIGINT)


def _stop_dies(rig: Rig, rng: random.Random) -> None:
    """The reply line dies as the stop arrives, the stop sent for a cut supply."""
    rig.simulation.emulator.go_silent_at_stop()
    _daq(rig).fail("supply-cut")


def _cut_before_the_zeroing(rig: Rig, rng: random.Random) -> None:
    """The wire cut 0.1-0.2 s into the zeroing's own acquisition, before the run's."""
    rig.clock.wait_for(lambda: rig.simulation.daq_tasks, 60.0)
    rig.clock.sleep(rng.uniform(0.1, 0.2))
    _daq(rig).fail("vout-floating")


def _burst_now(rig: Rig, rng: random.Random) -> None:
    """The specimen opens to the air at the volume the pump has supplied now."""
    from labrig.sim.specimen import SpecimenBehaviour

    emulator = rig.simulation.emulator
    rig.simulation.plant.behaviour = SpecimenBehaviour(
        emulator.net_volume_ml, burst_at_ml=emulator.net_volume_ml(rig.clock.now())
    )


def _left_infusing(emulator, rng: random.Random) -> None:
    """Another program's run left going: a few hundredths of a mL pushed before labrig
    connects (more inflates the specimen, and the zeroing then refuses the run)."""
    emulator.keypad(f"irate {rng.uniform(0.6, 1.8):.3f} ml/min", "irun")
    emulator.clock.sleep(rng.uniform(0.2, 1.0))


def _said_at_connect(*words: str) -> Callable[[Rig, Path], list[str]]:
    """The run file's record of what connect found holds ``words``."""

    def check(rig: Rig, path: Path) -> list[str]:
        try:
            with open_run(path) as run:
                said = run["entry/pump_identity/at_connect"][()].decode()
        except (OSError, KeyError) as exc:
            return [f"the run file has no record of the pump at connect ({exc})"]
        return [] if all(w in said for w in words) else [f"at connect: {said!r}"]

    return check


def _another_pump(rig: Rig, rng: random.Random) -> None:
    emulator = rig.simulation.emulator
    emulator.re_enumerate(rng.uniform(0.1, 1.0), emulator.another_pump())


def _other_pump_untouched(rig: Rig, path: Path) -> list[str]:
    emulator = rig.simulation.emulator
    other = emulator.answering
    if other is emulator.firmware:
        return ["the other pump never answered behind the link"]
    sent = [line for line in other.executed if line.startswith(("stop", "stp"))]
    return [f"the other pump was sent {sent}"] if sent else []


def _slow_confirmation(rig: Rig, rng: random.Random) -> None:
    """Replies to stops and polls take longer than the half second once allowed (a
    pump redrawing after an alarm), within the reply timeout; then the sensor dies."""
    rig.simulation.emulator.slow_replies(rng.uniform(0.55, 0.8), ("stop", "status"))
    _daq(rig).fail("vout-cut")


FAULTS: dict[str, Fault] = {
    "sensor-vout-cut": Fault(
        lambda rig, rng: _daq(rig).fail("vout-cut"), "outside the sensor's range"
    ),
    "sensor-supply-cut": Fault(lambda rig, rng: _daq(rig).fail("supply-cut"), "not a number"),
    "sensor-frozen": Fault(
        lambda rig, rng: _daq(rig).fail("frozen"),
        "pressure reading frozen",
        window_s=IN_RANGE_DEATH_WINDOW_S,
        stop_s=IN_RANGE_DEATH_STOP_S,
    ),
    "daq-stall": Fault(lambda rig, rng: _daq(rig).fail("stall"), "pressure: no sample"),
    "daq-unplugged": Fault(lambda rig, rng: _daq(rig).fail("vanish"), "cannot be reached"),
    "pump-silent": Fault(
        lambda rig, rng: rig.simulation.emulator.go_silent(),
        "no complete reply from the pump",
        unconfirmed=True,
    ),
    "camera-stops": Fault(
        lambda rig, rng: rig.simulation.camera.stop_frames(), "camera: no sample"
    ),
    # the sensor's output wire cut during the run: the pull-up holds the open input
    # above the sensor's band
    "floating-wire": Fault(
        lambda rig, rng: _daq(rig).fail("vout-floating"), "pressure sensor wire open"
    ),
    # cut before the run: the zeroing reads above the band, nothing moves
    "wire-cut-before": Fault(
        _cut_before_the_zeroing,
        "its output wire is open",
        window_s=(0, 0),
        before_recording=True,
    ),
    # the specimen bursts (or a fitting comes off) while the pump infuses
    "specimen-burst": Fault(_burst_now, "the specimen lost pressure", window_s=(2.5, 9.0)),
    "camera-clock-jump": Fault(
        lambda rig, rng: rig.simulation.camera.jump_clock(rng.choice((-1, 1)) * rng.uniform(2, 30)),
        "the camera's clock jumped",
    ),
    "pump-stop-unconfirmed": Fault(_stop_dies, "not a number", unconfirmed=True),
    "pump-re-enumerates": Fault(
        lambda rig, rng: rig.simulation.emulator.re_enumerate(rng.uniform(0.1, 1.0)),
        "pump: lost the serial port",
    ),
    "sigterm": Fault(
        _send(signal.SIGTERM),
        "stopped by SIGTERM",
        status="aborted",
        speed=SIGNAL_SPEED,
        window_s=SIGNAL_WINDOW_S,
    ),
    "sighup": Fault(
        _send(signal.SIGHUP),
        "(SIGHUP)",
        status="aborted",
        speed=SIGNAL_SPEED,
        window_s=SIGNAL_WINDOW_S,
    ),
    "ctrl-c-paced": Fault(
        _send(signal.SIGINT),
        "stopped by the operator (Ctrl-C)",
        status="aborted",
        speed=SIGNAL_SPEED,
        window_s=SIGNAL_WINDOW_S,
    ),
    "ctrl-c-holding": Fault(
        _ctrl_c_in_the_hold,
        "stopped by the operator (Ctrl-C)",
        status="aborted",
        speed=SIGNAL_SPEED,
        window_s=(2.5, 5.0),
    ),
    "pump-running-at-connect": Fault(
        lambda rig, rng: _daq(rig).fail("vout-cut"),
        "outside the sensor's range",
        before_connect=_left_infusing,
        check=_said_at_connect("the pump was infusing at", "labrig stopped it"),
    ),
    "quick-start": Fault(
        lambda rig, rng: _daq(rig).fail("supply-cut"),
        "not a number",
        before_connect=lambda emulator, rng: emulator.keypad(f"load qs {rng.choice('iw')}"),
        check=_said_at_connect("labrig loaded Quick Start on the pump ('load qs iw')"),
    ),
    "another-pump-at-the-link": Fault(
        _another_pump,
        "not the pump of this run",
        unconfirmed=True,
        check=_other_pump_untouched,
    ),
    "slow-confirmation": Fault(_slow_confirmation, "outside the sensor's range"),
}


@dataclass(frozen=True)
class RunVerdict:
    """One soak run: its fault, what happened, and each check's outcome."""

    run: int
    fault: str
    fault_s: float  # rig seconds after the run started
    status: str
    reason: str
    stopped_after_s: float  # rig seconds from the fault to the plunger's last movement
    finalised: bool
    samples_kept: bool
    frames_kept: bool
    rss_mb: float
    wall_s: float
    problems: tuple[str, ...]

    @property
    def safe(self) -> bool:
        return not self.problems


@dataclass(frozen=True)
class SoakSummary:
    runs: int
    safe: int
    seed: int
    faults: dict[str, int]
    max_stop_s: float
    rss_start_mb: float
    rss_end_mb: float
    memory_flat: bool
    wall_s: float

    @property
    def ok(self) -> bool:
        return self.safe == self.runs and self.memory_flat

    def line(self) -> str:
        kinds = ", ".join(f"{kind} {n}" for kind, n in sorted(self.faults.items()))
        return (
            f"soak {'PASS' if self.ok else 'FAIL'}: {self.safe}/{self.runs} runs safe "
            f"(seed {self.seed}; {kinds}); pump stopped at most {self.max_stop_s:.2f} s "
            f"after the fault where its stop was confirmed ({MAX_STOP_S:g} s allowed, "
            f"{IN_RANGE_DEATH_STOP_S:g} s for a sensor dead in range); memory "
            f"{self.rss_start_mb:.0f} -> {self.rss_end_mb:.0f} MB "
            f"({'flat' if self.memory_flat else 'GROWING'}); {self.wall_s:.0f} s"
        )


def _told_unconfirmed(verdict: RunVerdict) -> bool:
    return verdict.reason.startswith(PUMP_STOP_NOT_CONFIRMED)


def resident_mb() -> float:
    """This process's resident memory now (Linux), else its peak."""
    with contextlib.suppress(OSError, ValueError, IndexError):
        pages = int(Path("/proc/self/statm").read_text().split()[1])
        return pages * resource.getpagesize() / 2**20
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024


def fault_plan(runs: int, seed: int) -> list[tuple[str, float]]:
    """(fault, rig time after the start) per run: every kind in turn from a shuffled
    order, so each comes ``runs // len(FAULTS)`` times or once more; times uniform."""
    rng = random.Random(seed)
    kinds = list(FAULTS)
    rng.shuffle(kinds)
    plan = []
    for i in range(runs):
        kind = kinds[i % len(kinds)]
        plan.append((kind, rng.uniform(*(FAULTS[kind].window_s or FAULT_WINDOW_S))))
    return plan


def soak(
    runs: int, seed: int, on_run: Callable[[RunVerdict], None] | None = None
) -> tuple[SoakSummary, list[RunVerdict]]:
    """Run the soak; ``on_run`` sees each run's verdict as it comes."""
    wall0 = time.monotonic()
    verdicts = []
    with tempfile.TemporaryDirectory(prefix="labrig-soak-") as tmp:
        protocol_path = Path(tmp) / "soak.yaml"
        protocol_path.write_text(PROTOCOL, encoding="utf-8")
        loaded = load_protocol(protocol_path)
        for i, (kind, fault_s) in enumerate(fault_plan(runs, seed)):
            verdict = _one_run(loaded, Path(tmp) / "run.h5", i, kind, fault_s, seed)
            gc.collect()  # the run's rig gone before its memory is read
            verdict = replace(verdict, rss_mb=round(resident_mb(), 1))
            verdicts.append(verdict)
            if on_run is not None:
                on_run(verdict)
    warm = verdicts[min(len(verdicts) - 1, max(5, runs // 10))].rss_mb if verdicts else 0.0
    end = verdicts[-1].rss_mb if verdicts else 0.0
    summary = SoakSummary(
        runs=runs,
        safe=sum(v.safe for v in verdicts),
        seed=seed,
        faults=dict(Counter(v.fault for v in verdicts)),
        # where the run said its stop was not confirmed (another pump at the link), the
        # plunger is the operator's to stop: it runs on by design, and says nothing of
        # how fast labrig stops a pump
        max_stop_s=max(
            (v.stopped_after_s for v in verdicts if not _told_unconfirmed(v)), default=0.0
        ),
        rss_start_mb=warm,
        rss_end_mb=end,
        memory_flat=end - warm < RSS_GROWTH_LIMIT_MB,
        wall_s=time.monotonic() - wall0,
    )
    return summary, verdicts


def _one_run(loaded, path: Path, index: int, kind: str, fault_s: float, seed: int) -> RunVerdict:
    wall0 = time.monotonic()
    fault = FAULTS[kind]
    config = RigConfig(
        pump=PumpConfig(port="emulator"),
        # the supply measured, as the docs advise: a cut supply then reads NaN
        pressure=PressureConfig(supply_channel="Dev1/ai1"),
        sim=SimConfig(seed=seed * 1009 + index, reply_timeout_s=REPLY_TIMEOUT_S, speed=fault.speed),
    )
    rng = random.Random(seed * 7919 + index)
    left = fault.before_connect
    rig = build_simulated_rig(
        loaded.protocol, config, None if left is None else lambda emulator: left(emulator, rng)
    )
    rig.simulation.capture.first_frame_s = rng.uniform(*CAMERA_FIRST_FRAME_S)
    start_s = rig.clock.now()
    struck_at_s = [start_s + fault_s]

    def strike() -> None:
        rig.clock.sleep(struck_at_s[0] - rig.clock.now())
        fault.inflict(rig, rng)
        struck_at_s[0] = rig.clock.now()  # a fault that waits for its moment (the hold)
        rig.simulation.disk.write_s = SLOW_WRITE_S

    with rig.clock.participate():
        rig.clock.start_thread(strike, "fault")
        result = Runner(loaded, rig, path, data_tap=rig.simulation.disk.write).run()
    end_s = rig.clock.now()
    fault_at_s = struck_at_s[0]
    problems = []
    if result.status != fault.status or fault.reason not in result.reason:
        problems.append(f"ended {result.status}: {result.reason!r}")
    told = result.reason.startswith(PUMP_STOP_NOT_CONFIRMED)
    if told == result.stop_confirmed:
        problems.append(f"stop confirmed {result.stop_confirmed}, reason {result.reason!r}")
    if fault.unconfirmed and result.stop_confirmed:
        problems.append("the stop was confirmed by a pump that cannot answer")
    stopped_after_s = _stopped_after_s(rig, fault_at_s, end_s)
    if stopped_after_s > fault.stop_s and result.stop_confirmed:
        problems.append(f"the plunger moved until {stopped_after_s:.2f} s after the fault")
    # a fault before the recording starts leaves nothing to keep
    kept_from_s = -np.inf if fault.before_recording else fault_at_s
    finalised, samples_kept, frames_kept = _check_file(path, result, kept_from_s, problems)
    if fault.check is not None:
        problems.extend(fault.check(rig, path))
    path.unlink(missing_ok=True)
    return RunVerdict(
        run=index,
        fault=kind,
        fault_s=round(fault_s, 3),
        status=result.status,
        reason=result.reason,
        stopped_after_s=round(stopped_after_s, 3),
        finalised=finalised,
        samples_kept=samples_kept,
        frames_kept=frames_kept,
        rss_mb=0.0,  # read by the caller once the run's objects are collected
        wall_s=round(time.monotonic() - wall0, 2),
        problems=tuple(problems),
    )


def _stopped_after_s(rig: Rig, fault_at_s: float, end_s: float) -> float:
    """Rig seconds from the fault to the plunger's last movement (0: it stood still),
    from the emulated firmware's volume on a 10 ms grid up to well after the run."""
    emulator = rig.simulation.emulator
    grid = np.arange(fault_at_s, end_s + 30.0, 0.01)
    volume = np.array([emulator.net_volume_ml(t) for t in grid])
    moving = np.flatnonzero(np.abs(volume - volume[-1]) > 1e-9)
    return 0.0 if len(moving) == 0 else float(grid[moving[-1] + 1] - fault_at_s)


def _check_file(path: Path, result, fault_at_s: float, problems: list[str]):
    """Finalised with the run's status and reason; every pressure sample from the first
    to the fault there, evenly spaced; the frames up to the camera's allowance before
    (nothing before a fault at -inf)."""
    try:
        with open_run(path) as run:
            entry = run["entry"]
            status = entry["status"][()].decode()
            reason = entry["reason"][()].decode()
            pressure = read_log(run, 1, "pressure").time_s
            frames = read_log(run, 1, "length").time_s
    except (OSError, KeyError) as exc:
        problems.append(f"the run file cannot be read: {exc}")
        return False, False, False
    finalised = status == result.status and reason == result.reason[: len(reason)]
    if not finalised:
        problems.append(f"the file says {status!r} ({reason!r}), the run {result.status!r}")
    period_s = 1.0 / PRESSURE_RATE_HZ
    before = pressure[pressure < fault_at_s]
    samples_kept = fault_at_s == -np.inf or (
        len(before) > 0
        and np.all(np.abs(np.diff(before) - period_s) < 0.01 * period_s)
        and before[-1] >= fault_at_s - 1.5 * period_s
    )
    if not samples_kept:
        problems.append(
            f"pressure samples before the fault missing ({len(before)} kept, the last at "
            f"{before[-1] if len(before) else float('nan'):.3f} s, the fault at {fault_at_s:.3f} s)"
        )
    frame_s = 1.0 / CAMERA_FPS
    seen = frames[frames < fault_at_s]
    frames_kept = fault_at_s == -np.inf or (
        len(seen) > 0
        and np.all(np.abs(np.diff(seen) - frame_s) < 0.01 * frame_s)
        and seen[-1] >= fault_at_s - 0.5 - frame_s
    )
    if not frames_kept:
        problems.append(
            f"camera frames before the fault missing ({len(seen)} kept, the last at "
            f"{seen[-1] if len(seen) else float('nan'):.3f} s, the fault at {fault_at_s:.3f} s)"
        )
    return finalised, bool(samples_kept), bool(frames_kept)


def verdict_dict(verdict: RunVerdict) -> dict:
    return {**asdict(verdict), "safe": verdict.safe}
