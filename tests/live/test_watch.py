"""``labrig watch RUN.h5``: the live page of a run another process records, read from
the growing file (SWMR)."""

from __future__ import annotations

import re
import subprocess
import sys
import threading

from support.liverun import PROTOCOL, get, poll_until

from labrig.live.state import STATE_FIELDS


def test_watch_follows_a_run_recorded_by_another_process(tmp_path):
    out = tmp_path / "watched.h5"
    recorder = subprocess.Popen(
        [sys.executable, "-m", "labrig", "run", str(PROTOCOL), "--sim", "--speed", "10",
         "--out", str(out)],
        stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
    )  # fmt: skip
    watcher = None
    try:
        poll_until(lambda: out.exists(), "the run file")
        watcher = subprocess.Popen(
            [sys.executable, "-m", "labrig", "watch", str(out), "--live-hold", "5"],
            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True,
        )  # fmt: skip
        lines: list[str] = []
        threading.Thread(target=lambda: lines.extend(watcher.stderr), daemon=True).start()
        url = poll_until(
            lambda: next((m.group(1) for s in lines if (m := re.search(r"(http://\S+)", s))), None),
            "the watch address",
        )
        first = poll_until(
            lambda: (s := get(url + "api/state"))["volume_ml"] and s["volume_ml"] > 0.5 and s,
            "a volume in the file",
        )
        assert tuple(first) == STATE_FIELDS
        assert first["status"] == "running"
        # each log of the file is refreshed on its own (SWMR): the volume and the time
        # may grow one poll apart
        poll_until(
            lambda: (
                (s := get(url + "api/state"))["volume_ml"] > first["volume_ml"]
                and s["t_s"] > first["t_s"]
                and s
            ),
            "a larger volume at a later time",
        )
        series = get(url + "api/series?pressure=0&length=0")
        assert len(series["pressure"]) > 10 and len(series["length"]) > 2
        final = poll_until(
            lambda: (s := get(url + "api/state"))["status"] != "running" and s, "the end"
        )
        assert final["status"] == "complete"
        assert final["step"] == "finished"
        poll_until(
            lambda: any(
                t["direction"] == "inflate" for t in get(url + "api/series")["transitions"]
            ),
            "the snap detected in the file's data",
        )
        # the watcher let go of the file: the recorder's analysis could write it
        output = recorder.communicate(timeout=300)[0]
        assert recorder.returncode == 0, output
        assert "analysis: not made" not in output
        assert watcher.wait(60) == 0
    finally:
        for proc in (recorder, watcher):
            if proc is not None and proc.poll() is None:
                proc.kill()
