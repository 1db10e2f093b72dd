"""The temporary folder of the simulated pump's stable link (its udev-like
``/dev/serial/by-id/...`` path): made for one rig and removed when the rig closes.

A process killed outright (SIGKILL, the out-of-memory killer, a crashed interpreter)
cannot remove it, so the folder's name carries its process's id, and every new folder
is made after removing those whose process is gone: stale folders never pile up in the
temporary directory, and a live run's link is never touched.
"""

from __future__ import annotations

import os
import re
import tempfile
from pathlib import Path

PREFIX = "labrig-sim-serial-"
# PREFIX, the owner's process id, a dash, then mkdtemp's random letters (no dash)
_NAME = re.compile(re.escape(PREFIX) + r"(\d+)-[A-Za-z0-9_]+")


def new_link_folder() -> Path:
    """A new empty folder for this process's pump link, stale ones removed first."""
    remove_stale_link_folders()
    return Path(tempfile.mkdtemp(prefix=f"{PREFIX}{os.getpid()}-"))


def remove_stale_link_folders(root: Path | None = None) -> list[Path]:
    """Remove the link folders under ``root`` (the temporary directory) whose process is
    no longer running, with the links in them; what they hold besides links, and folders
    that cannot be removed (another user's), stay. Returns the folders removed."""
    removed = []
    for folder in Path(root or tempfile.gettempdir()).glob(PREFIX + "*"):
        match = _NAME.fullmatch(folder.name)
        if match is None or _running(int(match[1])):
            continue
        try:
            for entry in folder.iterdir():
                if entry.is_symlink():
                    entry.unlink()
            folder.rmdir()
        except OSError:  # not ours to remove, or another new rig removed it first
            continue
        removed.append(folder)
    return removed


def _running(pid: int) -> bool:
    try:
        os.kill(pid, 0)  # no signal sent: only whether the process exists
    except ProcessLookupError:
        return False
    except PermissionError:  # it exists, another user's
        return True
    return True
