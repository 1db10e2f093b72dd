"""System sleep blocked while a run goes on, the laptop's lid switch too.

A laptop that suspends mid-run freezes the program while the pump, which has its own
clock, goes on to its step's target, and no interlock runs. So a run holds the
operating system's sleep inhibitor: ``systemd-inhibit`` on Linux, ``caffeinate`` on
macOS, ``SetThreadExecutionState`` on Windows. Closing the lid is another way to
suspend: logind acts on the lid switch whatever ``sleep`` inhibitors say (its
``LidSwitchIgnoreInhibited`` defaults to yes), unless a ``handle-lid-switch``
inhibitor is held, so on Linux that is asked for too, and where it is refused (or the
system has no such lock: macOS, Windows) the run says in one line that closing the lid
will suspend it. Where nothing is available it says so in one line and the run goes
on: a run is never refused for it.
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
# What logind is asked to hold off: sleep and idle, and with them its own handling of
# the lid switch (a lock logind honours even with LidSwitchIgnoreInhibited=yes)
WHAT_WITH_LID = "sleep:idle:handle-lid-switch"
WHAT = "sleep:idle"
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
            if held:
                _lid_not_held("Windows keeps its own lid action: set it to Do nothing")
            yield held
        return
    commands = _inhibitor_commands()
    if not commands:
        _not_blocked("no systemd-inhibit or caffeinate on this system")
        yield False
        return
    process, holds_lid, refusals = _first_held(commands)
    if process is None:
        _not_blocked(refusals[-1])
        yield False
        return
    if not holds_lid:
        tool = os.path.basename(process.args[0])
        _lid_not_held(refusals[0] if refusals else f"{tool} cannot hold it")
    try:
        yield True
    finally:
        _release(process)


def _first_held(
    commands: list[tuple[list[str], bool]],
) -> tuple[subprocess.Popen | None, bool, list[str]]:
    """The first of ``commands`` whose inhibitor holds (None if none does), whether it
    holds the lid switch, and the refusals of those tried before it."""
    refusals = []
    for command, holds_lid in commands:
        process, refusal = _start(command)
        if process is not None:
            return process, holds_lid, refusals
        refusals.append(refusal)
    return None, False, refusals


def _inhibitor_commands() -> list[tuple[list[str], bool]]:
    """Commands that hold an inhibitor until their standard input closes (or, for
    caffeinate, until this process ends: a killed run releases it too), to be tried in
    turn, each with whether it holds the lid switch as well."""
    if tool := shutil.which("systemd-inhibit"):
        return [
            (_systemd_inhibit(tool, WHAT_WITH_LID), True),
            (_systemd_inhibit(tool, WHAT), False),
        ]
    if tool := shutil.which("caffeinate"):
        return [([tool, "-i", "-w", str(os.getpid())], False)]
    return []


def _systemd_inhibit(tool: str, what: str) -> list[str]:
    return [tool, f"--what={what}", "--who=labrig", f"--why={WHY}", "--mode=block", "cat"]


def _start(command: list[str]) -> tuple[subprocess.Popen | None, str]:
    """The inhibitor's process once it holds, or None and why it did not."""
    try:
        process = subprocess.Popen(
            command,
            stdin=subprocess.PIPE,
            stdout=subprocess.DEVNULL,
            stderr=subprocess.PIPE,
        )
    except OSError as exc:
        return None, f"{command[0]} could not start: {exc}"
    try:
        process.wait(REFUSAL_WAIT_S)
    except subprocess.TimeoutExpired:
        return process, ""
    refusal = process.stderr.read().decode(errors="replace").strip().splitlines()
    process.stderr.close()
    process.stdin.close()
    return None, f"{os.path.basename(command[0])}: {refusal[-1] if refusal else 'refused'}"


def _release(process: subprocess.Popen) -> None:
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
        "system sleep is not blocked during this run (%s): keep the computer awake, "
        "and its lid open, until the run ends",
        why,
    )


def _lid_not_held(why: str) -> None:
    log.warning(
        "closing the laptop's lid will suspend the computer during this run (%s): keep it open",
        why,
    )
