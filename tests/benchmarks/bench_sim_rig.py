"""Benchmark: the simulated rig on virtual time. Prints numbers; asserts nothing.

Each shipped protocol is run as a technician runs it (`labrig run PROTOCOL --sim` in a
fresh process: start-up, the run, the analysis), and the recorded file is checked for
completeness: pressure samples, pump polls and camera frames against what the
protocol's rig time implies. Rig time over wall time is the speed-up; on virtual time
it changes with the host, the data do not.

The camera's cost: the demo run at 2 fps without video against the shipped 30 fps,
without and with ``video: true``; the wall time of the whole process and
of the run alone (the "simulated ... in X s" line), the process's CPU time (user + system,
all threads: what the camera costs, whatever else the machine is running), the load
average, and the video's frames.

Then the ratio whose target is 1.5: 30 fps with video over 2 fps without, in
interleaved pairs (A/B/A/B), each pair's ratio and their range.

Where the demo's CPU time goes (``--profile``): the demo run in a process whose parts
(the start-up, the plant, the DAQ, the interlocks, the pump's exchanges, the camera, the
writer thread, the virtual clock's hand-overs, the analysis, the interpreter's exit)
are timed on their threads' CPU clocks (``sim_rig_profile.py``), beside the marker
tracker's process. With ``--before CHECKOUT`` (a checkout of an earlier commit with its
own ``.venv``) the same is measured there, in interleaved pairs, and the whole process's
speed-up before and after. Beside it, what one hand-over of the virtual clock costs,
back to the same thread and between threads.

Each checkout's bytecode is compiled first (``compileall``), as any install's first
command leaves it: a process that finds none (``PYTHONDONTWRITEBYTECODE`` set, as on
some CI machines) compiles labrig's modules again at every start.

Run: python tests/benchmarks/bench_sim_rig.py [--burners N] [--camera-only] [--pairs N]
     [--profile [--before CHECKOUT]] [--write-docs]
(--burners 2 runs two CPU-burning processes alongside, as on a busy CI machine.)
"""

import argparse
import json
import os
import re
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import h5py
import numpy as np

from labrig.cli.performance_doc import add_write_docs_argument, markdown_table, script_doc

ROOT = Path(__file__).resolve().parents[2]
PROTOCOLS = ("demo.yaml", "combined_actuator.yaml")


def completeness(path: Path) -> tuple[float, int, int, int, int, int, int]:
    """Rig time of the repetitions, and per series: recorded and expected counts."""
    with h5py.File(path, "r") as f:
        reps = f["entry/repetitions"]
        rig_s = float(np.sum(reps["t_end"][:] - reps["t_start"][:]))
        counts = {"pressure": [0, 0], "pump": [0, 0], "length": [0, 0]}
        for name in reps:
            if not name.startswith("rep_"):
                continue
            fps = float(re.search(r"camera_fps: ([0-9.]+)", f["entry/protocol"][()].decode())[1])
            for log, period_s in (("pressure", 0.001), ("pump", 0.2), ("length", 1 / fps)):
                t = reps[name][log]["time"][:]
                counts[log][0] += len(t)
                # a regular grid: the span over the period, plus the first reading
                # (pump: plus one re-phased poll at each motion start)
                extra = int(np.sum(np.diff(t) < period_s - 1e-9)) if log == "pump" else 0
                counts[log][1] += round((t[-1] - t[0]) / period_s) + 1 + extra
    return rig_s, *counts["pressure"], *counts["pump"], *counts["length"]


def cache_bytecode(checkout: Path) -> None:
    """Compile the checkout's modules to bytecode, as an install's first command does."""
    subprocess.run(
        [python_of(checkout), "-m", "compileall", "-q", "labrig", "sim", "drivers"],
        check=True,
        capture_output=True,
        cwd=checkout,
    )


def run_protocol(protocol: Path, out: Path) -> tuple[float, float, float]:
    """(wall time of the process, wall time of the run itself, CPU time of the process)
    of `labrig run --sim`."""
    wall0 = time.monotonic()
    cpu0 = _children_cpu_s()
    done = subprocess.run(
        [sys.executable, "-m", "labrig", "run", str(protocol), "--sim", "--out", str(out)],
        check=True,
        capture_output=True,
        text=True,
    )
    run_s = float(re.search(r"rig\s+time\s+in\s+([0-9.]+)\s+s", done.stdout + done.stderr)[1])
    return time.monotonic() - wall0, run_s, _children_cpu_s() - cpu0


def _children_cpu_s() -> float:
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return usage.ru_utime + usage.ru_stime


def camera_cost(tmp: Path, video: bool = True) -> str:
    """The demo at 2 fps without video, at 30 fps without and with video: a table."""
    demo = (ROOT / "protocols" / "demo.yaml").read_text()
    variants = {
        "2 fps, no video": demo.replace("camera_fps: 30}", "camera_fps: 2}"),
        "30 fps, no video": demo,
        "30 fps, video": demo.replace("camera_fps: 30}", "camera_fps: 30, video: true}"),
    }
    if not video:
        del variants["30 fps, video"]
    base = None
    rows = []
    for k, (name, text) in enumerate(variants.items()):
        protocol = tmp / f"demo_{k}.yaml"
        protocol.write_text(text)
        out = tmp / f"demo_{k}.h5"
        wall_s, run_s, cpu_s = run_protocol(protocol, out)
        load = os.getloadavg()[0]
        base = base or (wall_s, run_s, cpu_s)
        *_, frames, _ = completeness(out)
        video_file = out.with_suffix(".avi")
        in_video = "-"
        if video_file.exists():
            import cv2

            capture = cv2.VideoCapture(str(video_file))
            in_video = f"{int(capture.get(cv2.CAP_PROP_FRAME_COUNT)):,}"
            in_video += f" ({video_file.stat().st_size / 1e6:.0f} MB)"
        rows.append(
            (
                name,
                f"{wall_s:.1f}",
                f"{run_s:.1f}",
                f"{wall_s / base[0]:.2f}",
                f"{run_s / base[1]:.2f}",
                f"{cpu_s:.1f}",
                f"{cpu_s / base[2]:.2f}",
                f"{load:.1f}",
                f"{frames:,}",
                in_video,
                snap_dl(out),
            )
        )
    header = (
        "demo.yaml",
        "process (s)",
        "run (s)",
        "x process",
        "x run",
        "CPU (s)",
        "x CPU",
        "load",
        "frames",
        "video frames",
        "snap (2,1) dl (mm)",
    )
    return markdown_table(header, rows, right=set(range(1, 10)))


def video_ratio(tmp: Path, pairs: int) -> str:
    """The demo at 30 fps with video against 2 fps without, run A/B/A/B (``pairs``
    times each) so that the load from other work falls on both: each pair's ratio of
    process wall time, run wall time and CPU time, then their ranges, as a table."""
    demo = (ROOT / "protocols" / "demo.yaml").read_text()
    a, b = tmp / "ratio_2fps.yaml", tmp / "ratio_30fps_video.yaml"
    a.write_text(demo.replace("camera_fps: 30}", "camera_fps: 2}"))
    b.write_text(demo.replace("camera_fps: 30}", "camera_fps: 30, video: true}"))
    ratios, rows = [], []
    for k in range(pairs):
        (wa, ra, ca), (wb, rb, cb) = (
            run_protocol(p, tmp / f"ratio_{k}_{p.stem}.h5") for p in (a, b)
        )
        ratios.append((wb / wa, rb / ra, cb / ca))
        rows.append(
            (
                k + 1,
                f"{wa:.1f}",
                f"{wb:.1f}",
                f"{wb / wa:.2f}",
                f"{rb / ra:.2f}",
                f"{cb / ca:.2f}",
                f"{os.getloadavg()[0]:.1f}",
            )
        )
    lo, hi = np.min(ratios, axis=0), np.max(ratios, axis=0)
    rows.append(("range", "", "", *(f"{lo[i]:.2f}-{hi[i]:.2f}" for i in range(3)), ""))
    header = ("pair", "2 fps (s)", "30 fps + video (s)", "x process", "x run", "x CPU", "load")
    return markdown_table(header, rows, right=set(range(1, 7)))


def snap_dl(path: Path) -> str:
    """The demo's snap (2,1): measured against the model's length change."""
    done = subprocess.run(
        [sys.executable, "-m", "labrig", "compare", str(path), "--json"],
        check=True,
        capture_output=True,
        text=True,
    )
    for t in json.loads(done.stdout)["transitions"]:
        if (t["type"], t["alpha"], t["beta"]) == ("snap", 2, 1) and t["dl_meas_mm"] is not None:
            return f"{t['dl_meas_mm']:+.2f} (model {t['dl_mm']:+.2f})"
    return "not measured"


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--burners", type=int, default=0)
    parser.add_argument("--camera-only", action="store_true")
    parser.add_argument("--no-video", action="store_true", help="leave the video run out")
    parser.add_argument(
        "--pairs", type=int, default=3, help="A/B pairs of 2 fps against 30 fps with video"
    )
    parser.add_argument(
        "--profile", action="store_true", help="only where the demo's CPU time goes"
    )
    parser.add_argument(
        "--before",
        type=Path,
        help="with --profile: a checkout of an earlier commit (with its own .venv) to "
        "measure against, in interleaved pairs",
    )
    add_write_docs_argument(parser)
    args = parser.parse_args()
    for checkout in ([args.before] if args.before else []) + [ROOT]:
        cache_bytecode(checkout)
    if args.profile:
        profile_main(args)
        return
    sections = ["sim-rig-camera"]
    if not args.no_video and args.pairs > 0:
        sections.append("sim-rig-video")
    if not args.camera_only:
        sections.append("sim-rig")
    doc = script_doc(sections, args.write_docs)
    burners = [
        subprocess.Popen([sys.executable, "-c", "while True: pass"]) for _ in range(args.burners)
    ]
    print(f"{args.burners} CPU-burning processes alongside")
    try:
        with tempfile.TemporaryDirectory() as tmp:
            doc.publish("sim-rig-camera", camera_cost(Path(tmp), video=not args.no_video))
            if "sim-rig-video" in sections:
                doc.publish("sim-rig-video", video_ratio(Path(tmp), args.pairs))
            if "sim-rig" in sections:
                doc.publish("sim-rig", protocols(Path(tmp)))
    finally:
        for burner in burners:
            burner.kill()


def protocols(tmp: Path) -> str:
    """Each shipped protocol run once: its speed-up and what its file kept, a table."""
    rows = []
    for name in PROTOCOLS:
        out = tmp / f"{name}.h5"
        wall0 = time.monotonic()
        protocol = str(ROOT / "protocols" / name)
        subprocess.run(
            [sys.executable, "-m", "labrig", "run", protocol, "--sim", "--out", str(out)],
            check=True,
            capture_output=True,
        )
        wall_s = time.monotonic() - wall0
        rig_s, p, p_exp, q, q_exp, f, f_exp = completeness(out)
        rows.append(
            (
                name,
                f"{rig_s:,.0f}",
                f"{wall_s:.1f}",
                f"x{rig_s / wall_s:.0f}",
                f"{p:,} of {p_exp:,}",
                f"{q:,} of {q_exp:,}",
                f"{f:,} of {f_exp:,}",
            )
        )
    header = (
        "protocol",
        "rig time (s)",
        "wall (s)",
        "speed-up",
        "pressure samples",
        "pump polls",
        "frames",
    )
    return markdown_table(header, rows, right={1, 2, 3, 4, 5, 6})


def profile_main(args) -> None:
    sections = ["sim-rig-profile", "sim-rig-handovers"]
    sections += ["sim-rig-before-after"] if args.before else []
    doc = script_doc(sections, args.write_docs)
    checkouts = ([args.before] if args.before else []) + [ROOT]
    names = {checkout: commit_of(checkout) for checkout in checkouts}  # before any write
    pairs = max(args.pairs, 1)
    with tempfile.TemporaryDirectory() as tmp:
        profiles = {checkout: [] for checkout in checkouts}
        speeds = {checkout: [] for checkout in checkouts}
        for k in range(pairs):
            for checkout in checkouts:  # A/B/A/B: the load falls on both
                profiles[checkout].append(profile_demo(checkout, Path(tmp) / f"p{k}.h5"))
                print(f"profiled {checkout} ({k + 1} of {pairs})", file=sys.stderr)
            if args.before:
                for checkout in checkouts:
                    out = Path(tmp) / f"s{k}_{len(speeds[checkout])}.h5"
                    speeds[checkout].append(demo_speed(checkout, out))
        doc.publish("sim-rig-profile", profile_table(profiles, checkouts, names))
        doc.publish("sim-rig-handovers", handover_table())
        if args.before:
            doc.publish("sim-rig-before-after", before_after_table(speeds, checkouts, names))


def handover_cost(n_threads: int, turns: int = 3000) -> float:
    """CPU microseconds per hand-over of a ``VirtualClock`` whose ``n_threads`` threads
    each sleep 10 ms of clock time ``turns`` times, their wake-ups staggered so that
    they take turns (one thread: every hand-over is back to itself)."""
    from labrig.time.virtual import VirtualClock

    clock = VirtualClock()

    def sleeper(offset_s: float):
        def run() -> None:
            clock.sleep(offset_s)
            for _ in range(turns):
                clock.sleep(0.01)

        return run

    cpu0 = time.process_time()
    with clock.participate():
        threads = [
            clock.start_thread(sleeper(0.01 * k / n_threads), f"sleeper {k}")
            for k in range(n_threads)
        ]
        clock.wait_for(lambda: all(t.done for t in threads), 1e9)
    return 1e6 * (time.process_time() - cpu0) / (n_threads * turns)


def handover_table() -> str:
    """What one hand-over of the virtual clock costs, to itself and between threads
    (median of three)."""
    rows = []
    for n_threads, what in ((1, "back to the same thread"), (2, "2 threads"), (8, "8 threads")):
        cost_us = float(np.median([handover_cost(n_threads) for _ in range(3)]))
        rows.append((what, f"{cost_us:.1f}"))
    return markdown_table(("hand-overs", "CPU per hand-over (us)"), rows, right={1})


def commit_of(checkout: Path) -> str:
    """The checkout's commit, short (with + when its files differ from it)."""
    git = ["git", "-C", str(checkout)]
    commit = subprocess.run([*git, "rev-parse", "--short", "HEAD"], capture_output=True, text=True)
    changed = subprocess.run([*git, "diff", "--quiet", "HEAD"], capture_output=True).returncode
    return commit.stdout.strip() + ("+" if changed else "")


def python_of(checkout: Path) -> str:
    venv = checkout / ".venv" / "bin" / "python"
    return str(venv) if checkout != ROOT and venv.exists() else sys.executable


def profile_demo(checkout: Path, out: Path) -> dict:
    """The demo run under sim_rig_profile.py with ``checkout``'s labrig: CPU seconds
    per part, the tracker's process and the interpreter's exit included."""
    report = out.with_suffix(".json")
    cpu0 = _children_cpu_s()
    wall0 = time.monotonic()
    subprocess.run(
        [
            python_of(checkout),
            str(Path(__file__).with_name("sim_rig_profile.py")),
            str(checkout / "protocols" / "demo.yaml"),
            str(out),
            str(report),
        ],
        check=True,
        capture_output=True,
        cwd=checkout,
    )
    wall_s, total_cpu_s = time.monotonic() - wall0, _children_cpu_s() - cpu0
    data = json.loads(report.read_text())
    parts = data["cpu_s"]
    # what the parts leave of the process's CPU at its last atexit hook: the timing
    # itself; after it, the interpreter's end
    parts["timing the parts (its own cost)"] = data["process_cpu_s"] - sum(parts.values())
    parts["marker tracker's process"] = data["children_cpu_s"]
    parts["the interpreter's end"] = total_cpu_s - data["process_cpu_s"] - data["children_cpu_s"]
    out.unlink()
    return {"parts": parts, "calls": data["calls"], "wall_s": wall_s, "cpu_s": total_cpu_s}


def profile_table(profiles: dict, checkouts: list[Path], names: dict) -> str:
    """Median CPU seconds per part over the runs of each checkout."""
    after = profiles[ROOT]
    parts = sorted(
        {name for run in after for name in run["parts"]},
        key=lambda name: -np.median([run["parts"].get(name, 0.0) for run in after]),
    )

    def median(runs, name):
        return float(np.median([run["parts"].get(name, 0.0) for run in runs]))

    rows = []
    total_after = float(np.median([run["cpu_s"] for run in after]))
    for name in parts:
        cpu_s = median(after, name)
        if cpu_s < 0.005 and all(median(profiles[c], name) < 0.005 for c in checkouts):
            continue  # a thread that only waits
        calls = after[-1]["calls"].get(name, 0)
        calls = calls if calls > 1 else None  # a thread's whole life: no per-call figure
        row = [name]
        if len(checkouts) > 1:
            row.append(f"{median(profiles[checkouts[0]], name):.2f}")
        row += [
            f"{cpu_s:.2f}",
            f"{100 * cpu_s / total_after:.0f} %",
            f"{calls:,}" if calls else "",
            f"{1e6 * cpu_s / calls:.0f}" if calls else "",
        ]
        rows.append(row)
    total = ["whole run, all processes"]
    if len(checkouts) > 1:
        total.append(f"{np.median([run['cpu_s'] for run in profiles[checkouts[0]]]):.2f}")
    total += [f"{total_after:.2f}", "100 %", "", ""]
    rows.append(total)
    header = ["part of the demo (CPU of its threads)"]
    if len(checkouts) > 1:
        header += [f"before: {names[checkouts[0]]} (s)", f"{names[ROOT]} (s)"]
    else:
        header += ["CPU (s)"]
    header += ["share", "calls", "per call (us)"]
    return markdown_table(header, rows, right=set(range(1, len(header))))


def demo_speed(checkout: Path, out: Path) -> tuple[float, float, float, float]:
    """(process wall s, run wall s, CPU s, load) of the demo with ``checkout``'s labrig."""
    cpu0 = _children_cpu_s()
    wall0 = time.monotonic()
    done = subprocess.run(
        [python_of(checkout), "-m", "labrig", "run", "protocols/demo.yaml", "--sim", "--out", out],
        check=True,
        capture_output=True,
        text=True,
        cwd=checkout,
    )
    wall_s, cpu_s = time.monotonic() - wall0, _children_cpu_s() - cpu0
    run_s = float(re.search(r"rig\s+time\s+in\s+([0-9.]+)\s+s", done.stdout + done.stderr)[1])
    out.unlink()
    return wall_s, run_s, cpu_s, os.getloadavg()[0]


def before_after_table(speeds: dict, checkouts: list[Path], names: dict) -> str:
    """Each interleaved pair: the demo's whole process before and after."""
    before, after = (speeds[c] for c in checkouts)
    rows, ratios = [], []
    for k, (b, a) in enumerate(zip(before, after, strict=True)):
        ratios.append((a[0] / b[0], a[2] / b[2]))
        rows.append(
            (
                k + 1,
                f"{b[0]:.1f} (x{DEMO_RIG_S / b[0]:.0f})",
                f"{a[0]:.1f} (x{DEMO_RIG_S / a[0]:.0f})",
                f"{b[1]:.1f} / {a[1]:.1f}",
                f"{b[2]:.1f} / {a[2]:.1f}",
                f"{a[0] / b[0]:.2f}",
                f"{a[2] / b[2]:.2f}",
                f"{a[3]:.1f}",
            )
        )
    lo, hi = np.min(ratios, axis=0), np.max(ratios, axis=0)
    rows.append(("range", "", "", "", "", *(f"{lo[i]:.2f}-{hi[i]:.2f}" for i in range(2)), ""))
    header = (
        "pair",
        f"before: {names[checkouts[0]]}, process (s)",
        f"{names[checkouts[1]]}, process (s)",
        "run (s)",
        "CPU (s)",
        "x process",
        "x CPU",
        "load",
    )
    return markdown_table(header, rows, right=set(range(1, 8)))


DEMO_RIG_S = 372.0  # the demo's rig time (its repetitions' spans, ``completeness``)


if __name__ == "__main__":
    main()
