"""A simulated run with its live view, in a subprocess, for the live-view tests."""

from __future__ import annotations

import json
import re
import subprocess
import sys
import threading
import time
import urllib.request
from pathlib import Path

PROTOCOL = Path(__file__).parents[1] / "live" / "live_demo.yaml"


class LiveRun:
    """``labrig run PROTOCOL --sim --speed S --live`` in a subprocess; ``url`` is the
    page's address as printed. stderr is drained continuously (the run's progress line
    writes to it all the time), and kept for messages."""

    def __init__(self, protocol: Path, out: Path, *extra: str, speed: float = 10) -> None:
        self.command = [
            sys.executable, "-m", "labrig", "run", str(protocol), "--sim",
            "--speed", str(speed), "--out", str(out), *extra,
        ]  # fmt: skip
        self.out = out
        self.proc = subprocess.Popen(
            self.command, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True
        )
        self.lines: list[str] = []
        self._url = threading.Event()
        self.url = ""
        threading.Thread(target=self._drain, daemon=True).start()
        threading.Thread(target=self.proc.stdout.read, daemon=True).start()
        if not self._url.wait(120):
            self.stop()
            raise AssertionError("no live view address printed:\n" + "".join(self.lines))

    def _drain(self) -> None:
        for line in self.proc.stderr:
            self.lines.append(line)
            match = re.search(r"live view: (http://\S+)", line)
            if match and not self.url:
                self.url = match.group(1)
                self._url.set()

    def running(self) -> bool:
        return self.proc.poll() is None

    def wait(self, timeout_s: float = 300) -> int:
        return self.proc.wait(timeout_s)

    def stop(self) -> None:
        if self.running():
            self.proc.terminate()
            try:
                self.proc.wait(30)
            except subprocess.TimeoutExpired:
                self.proc.kill()


def poll_until(predicate, what: str, timeout_s: float = 180, every_s: float = 0.2):
    """predicate() until it returns something true; AssertionError naming ``what`` if
    it never does (a generous timeout: a slow machine only takes longer)."""
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        value = predicate()
        if value:
            return value
        time.sleep(every_s)
    raise AssertionError(f"timed out waiting for {what}")


def get(url: str):
    """The JSON a live page's address answers."""
    with urllib.request.urlopen(url, timeout=10) as response:
        return json.load(response)
