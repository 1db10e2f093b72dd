"""Benchmark: the simulated rig on virtual time. Prints numbers; asserts nothing.

Each shipped protocol is run as a technician runs it (`labrig run PROTOCOL --sim` in a
fresh process: start-up, the run, the analysis), and the recorded file is checked for
completeness: pressure samples, pump polls and camera frames against what the
protocol's rig time implies. Rig time over wall time is the speed-up; on virtual time
it changes with the host, the data do not.

Run: python tests/bench/bench_sim_rig.py [--burners N]
(--burners 2 runs two CPU-burning processes alongside, as on a busy CI machine.)
"""

import argparse
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
            for log, period_s in (("pressure", 0.001), ("pump", 0.2), ("length", 0.5)):
                t = reps[name][log]["time"][:]
                counts[log][0] += len(t)
                # a regular grid: the span over the period, plus the first reading
                # (pump: plus one re-phased poll at each motion start)
                extra = int(np.sum(np.diff(t) < period_s - 1e-9)) if log == "pump" else 0
                counts[log][1] += round((t[-1] - t[0]) / period_s) + 1 + extra
    return rig_s, *counts["pressure"], *counts["pump"], *counts["length"]


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--burners", type=int, default=0)
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
            for name in PROTOCOLS:
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
