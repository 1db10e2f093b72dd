"""Benchmark: the simulated rig on virtual time. Prints numbers; asserts nothing.

Each shipped protocol is run as a technician runs it (`labrig run PROTOCOL --sim` in a
fresh process: start-up, the run, the analysis), and the recorded file is checked for
completeness: pressure samples, pump polls and camera frames against what the
protocol's rig time implies. Rig time over wall time is the speed-up; on virtual time
it changes with the host, the data do not.

The camera's cost (issue 14): the demo run at the old 2 fps without video against the
shipped 30 fps, without and with ``video: true``; the wall time of the whole process and
of the run alone (the "simulated ... in X s" line), the process's CPU time (user + system,
all threads: what the camera costs, whatever else the machine is running), the load
average, and the video's frames.

Then the ratio issue 14 sets (<= 1.5): 30 fps with video over 2 fps without, in
interleaved pairs (A/B/A/B), each pair's ratio and their range.

Run: python tests/benchmarks/bench_sim_rig.py [--burners N] [--camera-only] [--pairs N]
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


def camera_cost(tmp: Path, video: bool = True) -> None:
    """The demo at 2 fps without video, at 30 fps without and with video."""
    demo = (ROOT / "protocols" / "demo.yaml").read_text()
    variants = {
        "2 fps, no video": demo.replace("camera_fps: 30}", "camera_fps: 2}"),
        "30 fps, no video": demo,
        "30 fps, video": demo.replace("camera_fps: 30}", "camera_fps: 30, video: true}"),
    }
    print(f"{'demo.yaml':<20} {'process s':>10} {'run s':>8} {'x process':>10} {'x run':>7} "
          f"{'CPU s':>6} {'x CPU':>6} {'load':>5} {'frames':>7} {'video frames':>13} "
          f"{'video MB':>9}  snap (2,1)")  # fmt: skip
    if not video:
        del variants["30 fps, video"]
    base = None
    for k, (name, text) in enumerate(variants.items()):
        protocol = tmp / f"demo_{k}.yaml"
        protocol.write_text(text)
        out = tmp / f"demo_{k}.h5"
        wall_s, run_s, cpu_s = run_protocol(protocol, out)
        load = os.getloadavg()[0]
        base = base or (wall_s, run_s, cpu_s)
        *_, frames, _ = completeness(out)
        video = out.with_suffix(".avi")
        n_video, size = "-", "-"
        if video.exists():
            import cv2

            capture = cv2.VideoCapture(str(video))
            n_video = str(int(capture.get(cv2.CAP_PROP_FRAME_COUNT)))
            size = f"{video.stat().st_size / 1e6:.0f}"
        print(
            f"{name:<20} {wall_s:10.1f} {run_s:8.1f} {wall_s / base[0]:10.2f} "
            f"{run_s / base[1]:7.2f} {cpu_s:6.1f} {cpu_s / base[2]:6.2f} {load:5.1f} "
            f"{frames:7d} {n_video:>13} {size:>9}  {snap_dl(out)}"
        )


def video_ratio(tmp: Path, pairs: int) -> None:
    """Issue 14's figure: the demo at 30 fps with video against 2 fps without, run
    A/B/A/B (``pairs`` times each) so that the load from other work falls on both; each
    pair's ratio of process wall time, run wall time and CPU time, then their ranges."""
    demo = (ROOT / "protocols" / "demo.yaml").read_text()
    a, b = tmp / "ratio_2fps.yaml", tmp / "ratio_30fps_video.yaml"
    a.write_text(demo.replace("camera_fps: 30}", "camera_fps: 2}"))
    b.write_text(demo.replace("camera_fps: 30}", "camera_fps: 30, video: true}"))
    print(f"\n{'demo, A/B pair':<16} {'2 fps s':>8} {'30+video s':>11} {'x process':>10} "
          f"{'x run':>6} {'x CPU':>6} {'load':>5}")  # fmt: skip
    ratios = []
    for k in range(pairs):
        (wa, ra, ca), (wb, rb, cb) = (run_protocol(p, tmp / f"ratio_{k}.h5") for p in (a, b))
        ratios.append((wb / wa, rb / ra, cb / ca))
        print(f"{k + 1:<16} {wa:8.1f} {wb:11.1f} {wb / wa:10.2f} {rb / ra:6.2f} {cb / ca:6.2f} "
              f"{os.getloadavg()[0]:5.1f}")  # fmt: skip
    lo, hi = np.min(ratios, axis=0), np.max(ratios, axis=0)
    print(f"{'range':<16} {'':8} {'':11} {lo[0]:4.2f}-{hi[0]:<5.2f} {lo[1]:.2f}-{hi[1]:.2f} "
          f"{lo[2]:.2f}-{hi[2]:.2f}   (target: x process <= 1.5)")  # fmt: skip


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
            return f"snap dl {t['dl_meas_mm']:+.2f} mm (model {t['dl_mm']:+.2f})"
    return "snap dl not measured"


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--burners", type=int, default=0)
    parser.add_argument("--camera-only", action="store_true")
    parser.add_argument("--no-video", action="store_true", help="leave the video run out")
    parser.add_argument(
        "--pairs", type=int, default=3, help="A/B pairs of 2 fps against 30 fps with video"
    )
    args = parser.parse_args()
    burners = [
        subprocess.Popen([sys.executable, "-c", "while True: pass"]) for _ in range(args.burners)
    ]
    print(f"{args.burners} CPU-burning processes alongside")
    print(
        f"{'protocol':<24} {'rig s':>7} {'wall s':>7} {'x':>5}  "
        f"{'pressure kept':>17} {'pump polls kept':>16} {'frames kept':>12}"
    )
    try:
        with tempfile.TemporaryDirectory() as tmp:
            camera_cost(Path(tmp), video=not args.no_video)
            if not args.no_video and args.pairs > 0:
                video_ratio(Path(tmp), args.pairs)
            for name in () if args.camera_only else PROTOCOLS:
                out = Path(tmp) / f"{name}.h5"
                wall0 = time.monotonic()
                protocol = str(ROOT / "protocols" / name)
                subprocess.run(
                    [sys.executable, "-m", "labrig", "run", protocol, "--sim", "--out", str(out)],
                    check=True,
                    capture_output=True,
                )
                wall_s = time.monotonic() - wall0
                rig_s, p, p_exp, q, q_exp, f, f_exp = completeness(out)
                print(
                    f"{name:<24} {rig_s:7.1f} {wall_s:7.1f} {rig_s / wall_s:5.0f}  "
                    f"{p:>8}/{p_exp:<8} {q:>7}/{q_exp:<8} {f:>5}/{f_exp:<6}"
                )
    finally:
        for burner in burners:
            burner.kill()


if __name__ == "__main__":
    main()
