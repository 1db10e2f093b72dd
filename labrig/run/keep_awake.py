"""System sleep blocked while a run goes on.

A laptop that suspends mid-run freezes the program while the pump, which has its own
clock, goes on to its step's target. So a run holds the operating system's sleep
inhibitor: ``systemd-inhibit`` on Linux, ``caffeinate`` on macOS,
``SetThreadExecutionState`` on Windows. Where none is available it says so in one
line and the run goes on: a run is never refused for it.
"""

from __future__ import annotations

import contextlib
import logging
import os
import shutil
import subprocess
import sys
from collections.abc import Iterator

log = logging.getLogger(__name__)

WHY = "a labrig run is moving a syringe pump"
# How long an inhibitor may take to refuse (no logind, no permission) before it is
# taken to hold.
REFUSAL_WAIT_S = 0.2
# SetThreadExecutionState flags (winbase.h)
ES_CONTINUOUS = 0x80000000
ES_SYSTEM_REQUIRED = 0x00000001


@contextlib.contextmanager
def system_kept_awake() -> Iterator[bool]:
    """Sleep blocked for the ``with`` block; yields whether it is."""
    if sys.platform == "win32":
        with _windows_execution_state() as held:
            yield held
        return
    command = _inhibitor_command()
    if command is None:
        _not_blocked("no systemd-inhibit or caffeinate on this system")
        yield False
        return
    with _inhibitor(command) as held:
        yield held


def _inhibitor_command() -> list[str] | None:
    """A command that holds the inhibitor until its standard input closes (or, for
    caffeinate, until this process ends): a killed run releases it too."""
    if tool := shutil.which("systemd-inhibit"):
        return [tool, "--what=sleep:idle", "--who=labrig", f"--why={WHY}", "--mode=block", "cat"]
    if tool := shutil.which("caffeinate"):
        return [tool, "-i", "-w", str(os.getpid())]
    return None


@contextlib.contextmanager
def _inhibitor(command: list[str]) -> Iterator[bool]:
    try:
        process = subprocess.Popen(
            command,
            stdin=subprocess.PIPE,
            stdout=subprocess.DEVNULL,
            stderr=subprocess.PIPE,
        )
    except OSError as exc:
        _not_blocked(f"{command[0]} could not start: {exc}")
        yield False
        return
    try:
        process.wait(REFUSAL_WAIT_S)
    except subprocess.TimeoutExpired:
        held = True
    else:
        refusal = process.stderr.read().decode(errors="replace").strip().splitlines()
        _not_blocked(f"{os.path.basename(command[0])}: {refusal[-1] if refusal else 'refused'}")
        held = False
    try:
        yield held
    finally:
        if held:
            process.stdin.close()  # cat ends, and the inhibitor with it
            try:
                process.wait(2.0)
            except subprocess.TimeoutExpired:
                process.kill()
                process.wait()
        process.stderr.close()


@contextlib.contextmanager
def _windows_execution_state() -> Iterator[bool]:
    import ctypes

    kernel32 = ctypes.WinDLL("kernel32")
    if not kernel32.SetThreadExecutionState(ES_CONTINUOUS | ES_SYSTEM_REQUIRED):
        _not_blocked("SetThreadExecutionState refused")
        yield False
        return
    try:
        yield True
    finally:
        kernel32.SetThreadExecutionState(ES_CONTINUOUS)


def _not_blocked(why: str) -> None:
    log.warning(
        "system sleep is not blocked during this run (%s): keep the computer awake "
        "until the run ends",
        why,
    )
