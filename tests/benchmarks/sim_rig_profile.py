"""Where the simulated demo's CPU time goes: ``labrig run --sim`` in this process with
each part of the rig timed by its thread's CPU clock (``time.thread_time``).

Every part is timed exclusively (the time of the parts it calls is the callee's), so the
parts add up to the process's CPU time: a thread's CPU outside every named part is its
"rest". Waiting costs no CPU and shows nowhere; the virtual clock's hand-overs (the
dispatch and the thread switch that follows) are a part of their own. Timing a part
costs about a microsecond a call, small beside what each part does.

Run by bench_sim_rig.py --profile as ``python sim_rig_profile.py PROTOCOL OUT JSON``; it
writes the parts' CPU seconds and call counts to JSON.
"""

import atexit
import gc
import json
import resource
import sys
import threading
import time
from collections import defaultdict

_LOCAL = threading.local()
_CPU_S: dict[str, float] = defaultdict(float)
_CALLS: dict[str, int] = defaultdict(int)
_LOCK = threading.Lock()

# (module, class or None, function, part): the parts of the run, innermost wins
PARTS = (
    ("labrig.run.dry_run", None, "dry_run_report", "dry run (protocol check, model peak)"),
    ("labrig.rig.assembly", None, "build_rig", "rig build (plant tables, camera noise)"),
    ("labrig.cli.run", None, "_analyse", "analysis and summary after the run"),
    ("labrig.sim.plant", "Plant", "_step", "plant: integration"),
    ("labrig.sim.plant", "Plant", "_interpolate", "plant: queries"),
    ("labrig.sim.plant", "Plant", "_interpolate_one", "plant: queries"),
    ("labrig.sim.daq", "SimDaqTask", "_read_into", "DAQ simulation (samples, sensor)"),
    ("labrig.run.interlocks", "InterlockMonitor", "check_pressure", "interlocks: pressure"),
    ("labrig.run.interlocks", "InterlockMonitor", "check_pump", "interlocks: pump"),
    ("labrig.run.signal_watch", "SignalWatch", "overdue", "interlocks: signal watch"),
    ("labrig.run.acquisition", "Acquisition", "_read_pressure", "pressure loop: rest"),
    ("labrig.run.acquisition", "Acquisition", "_read_pump", "pump poll: driver side"),
    ("labrig.sim.pump", "PumpEmulator", "_serve", "pump emulator (serial side)"),
    ("labrig.sim.pump", "PumpEmulator", "_motion_event", "pump emulator: motion events"),
    ("labrig.sim.camera", "SimCamera", "read", "camera capture (frames' scenes)"),
    ("labrig.drivers.camera", "FrameSource", "_read_frames", "camera reader: rest"),
    ("labrig.run.acquisition", "Acquisition", "_read_lengths", "camera batches to the tracker"),
    ("labrig.run.background_writer", "BackgroundWriter", "_serve", "writer thread (HDF5)"),
    ("labrig.run.runner", "Runner", "_report_progress", "progress display"),
    ("labrig.time.virtual", "VirtualClock", "_wait", "virtual clock: hand-overs"),
    ("labrig.time.virtual", "VirtualClock", "_dispatch", "virtual clock: hand-overs"),
    ("labrig.time.virtual", "VirtualClock", "_await_turn", "virtual clock: hand-overs"),
)


def _timed(function, part: str):
    def timed(*args, **kwargs):
        stack = getattr(_LOCAL, "stack", None)
        if stack is None:
            stack = _LOCAL.stack = [[_root_part(), 0.0]]
        frame = [part, 0.0]
        stack.append(frame)
        t0 = time.thread_time()
        try:
            return function(*args, **kwargs)
        finally:
            spent = time.thread_time() - t0
            stack.pop()
            stack[-1][1] += spent
            with _LOCK:
                _CPU_S[part] += spent - frame[1]
                _CALLS[part] += 1

    timed.__wrapped__ = function
    return timed


def _root_part() -> str:
    name = threading.current_thread().name
    return "main thread: rest" if name == "MainThread" else f"{name}: rest"


def _install() -> None:
    import importlib

    for module_name, class_name, function_name, part in PARTS:
        module = importlib.import_module(module_name)
        owner = getattr(module, class_name) if class_name else module
        setattr(owner, function_name, _timed(getattr(owner, function_name), part))
    run = threading.Thread.run

    def thread_run(self):
        _LOCAL.stack = [[_root_part(), 0.0]]
        t0 = time.thread_time()
        try:
            run(self)
        finally:
            root = _LOCAL.stack[0]
            with _LOCK:
                _CPU_S[root[0]] += time.thread_time() - t0 - root[1]

    threading.Thread.run = thread_run


def _children_cpu_s() -> float:
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return usage.ru_utime + usage.ru_stime


def main() -> None:
    protocol, out, report = sys.argv[1:4]
    import labrig.cli

    # _install imports the rig's modules too, what the run command imports first: as the
    # command does, the collector paused for them and they frozen after, in a checkout
    # whose command does so (labrig.cli.start_up_uncollected)
    paused = hasattr(labrig.cli, "start_up_uncollected")
    if paused:
        gc.disable()
    _install()
    if paused:
        gc.freeze()
        gc.enable()
    start_up_cpu_s = time.process_time()
    _LOCAL.stack = [["main thread: rest", 0.0]]
    main_t0 = time.thread_time()

    def write() -> None:
        root = _LOCAL.stack[0]
        parts = dict(_CPU_S)
        parts["main thread: rest"] = parts.get("main thread: rest", 0.0) + (
            time.thread_time() - main_t0 - root[1]
        )
        parts["start-up (the interpreter, imports)"] = start_up_cpu_s
        with open(report, "w") as f:
            json.dump(
                {
                    "cpu_s": parts,
                    "calls": dict(_CALLS),
                    "process_cpu_s": time.process_time(),
                    "children_cpu_s": _children_cpu_s(),  # the marker tracker's process
                },
                f,
            )

    atexit.register(write)
    sys.argv = ["labrig", "run", protocol, "--sim", "--out", out]
    labrig.cli.main()


if __name__ == "__main__":
    main()
