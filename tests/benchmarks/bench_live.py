"""What the live view costs a run: the tap's cost per append, and a simulated run at a
fixed speed with and without the page (a browser polling 2.5 times a second, plus
five connections that hang mid-request), compared by what the run file holds.

Run: ``python tests/benchmarks/bench_live.py [--speed 20] [--write-docs]``. The run is
``tests/live/live_demo.yaml`` (2 repetitions, 117 s of rig time). A fixed speed fixes
the run's wall time; what the page could cost is data: pump readings and camera frames
a busy host thins out (every pressure sample is kept by the DAQ's buffer either way).
"""

from __future__ import annotations

import argparse
import json
import re
import socket
import subprocess
import sys
import threading
import time
import urllib.request
from pathlib import Path
from tempfile import TemporaryDirectory

import h5py
import numpy as np

from labrig.cli.performance_doc import add_write_docs_argument, markdown_table, script_doc
from labrig.config.protocol import load_protocol
from labrig.live.session import run_info
from labrig.live.state import LiveState

PROTOCOL = Path(__file__).parents[1] / "live" / "live_demo.yaml"


def tap_cost_us(n: int = 20_000) -> float:
    """Median cost of one ``LiveState.tap`` (what the writer's thread pays)."""
    state = LiveState(run_info(load_protocol(PROTOCOL).protocol))
    block = {"time": np.arange(200) * 1e-3, "value": np.ones(200), "out_of_range": np.zeros(200)}
    times = []
    for _ in range(n):
        start = time.perf_counter()
        state.tap(1, "pressure", block)
        times.append(time.perf_counter() - start)
    return float(np.median(times) * 1e6)


def counts(path: Path) -> dict[str, int]:
    with h5py.File(path, "r") as f:
        reps = f["entry/repetitions"]
        names = [n for n in reps if n.startswith("rep_")]
        return {
            log: sum(len(reps[n][log]["time"]) for n in names)
            for log in ("pressure", "pump", "length")
        }


def one_run(out: Path, speed: float, live: bool) -> tuple[float, dict[str, int], int]:
    command = [sys.executable, "-m", "labrig", "run", str(PROTOCOL), "--sim", "--speed",
               str(speed), "--out", str(out)]  # fmt: skip
    if live:
        command += ["--live", "--live-hold", "0"]
    wall = float("nan")
    proc = subprocess.Popen(command, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    polls = [0]
    stop = threading.Event()

    def browser(url: str) -> None:
        hung = []
        host, port = url.split("//")[1].strip("/").split(":")
        for _ in range(5):
            s = socket.create_connection((host, int(port)))
            s.sendall(b"GET /api/state HTTP/1.1\r\n")
            hung.append(s)
        since = 0
        while not stop.is_set():
            try:
                urllib.request.urlopen(url + "api/state", timeout=5).read()
                with urllib.request.urlopen(f"{url}api/series?pressure={since}", timeout=5) as r:
                    since = json.load(r)["next_pressure"]
                polls[0] += 1
            except OSError:
                break
            time.sleep(0.4)

    for line in proc.stderr:
        match = re.search(r"live view: (http://\S+)", line)
        if match:
            threading.Thread(target=browser, args=(match.group(1),), daemon=True).start()
        simulated = re.search(r"rig time in ([\d.]+) s", line)
        if simulated:
            wall = float(simulated.group(1))
    proc.wait()
    stop.set()
    return wall, counts(out), polls[0]


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--speed", type=float, default=20.0)
    add_write_docs_argument(parser)
    args = parser.parse_args()
    doc = script_doc(["live"], args.write_docs)
    tap_us = tap_cost_us()
    rows = []
    with TemporaryDirectory() as tmp:
        for live in (False, True, False, True):
            wall, n, polls = one_run(Path(tmp) / f"{live}.h5", args.speed, live)
            what = f"`--live`, {polls} polls + 5 hung" if live else "no page"
            rows.append(
                (what, f"{wall:.1f}", f"{n['pressure']:,}", f"{n['pump']:,}", f"{n['length']:,}")
            )
    header = ("run", "wall (s)", "pressure samples", "pump readings", "camera frames")
    table = markdown_table(header, rows, right={1, 2, 3, 4})
    doc.publish(
        "live",
        f"{table}\n\nAt x{args.speed:g}; the tap (what the run file's writer pays per "
        f"append for the page): median {tap_us:.2f} us.",
    )


if __name__ == "__main__":
    main()
