"""Reading a file a person named (a protocol, a rig file, a measured curve): only a
regular file, of bounded size, as text.

A path is whatever a protocol says, so it may name ``/dev/zero`` (read forever until
memory runs out), a FIFO (an open that waits for a writer forever) or a folder. The file
is opened without waiting (``O_NONBLOCK``: a FIFO's open returns at once) and checked on
the open descriptor, so what is checked is what is read.
"""

from __future__ import annotations

import os
import stat
from pathlib import Path

from labrig.errors import InputError

# protocols and rig files are a few kB; the limit only stops a mistaken path early
MAX_CONFIG_BYTES = 1_000_000
# a measured curve of 8000 rows is 200 kB
MAX_TABLE_BYTES = 50_000_000


def read_text_file(path: Path, *, what: str, max_bytes: int, encoding: str = "utf-8") -> str:
    """The text of the regular file at ``path``; InputError naming the file and what is
    wrong (``what``: "protocol file", ...). No byte of the file is ever shown."""
    try:
        fd = os.open(path, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0))
    except FileNotFoundError:
        raise InputError(f"{path}: no such {what}") from None
    except (OSError, ValueError) as exc:  # ValueError: a NUL in the path
        raise InputError(f"{path}: cannot open the {what} ({_reason(exc)})") from None
    mode = os.fstat(fd).st_mode
    if not stat.S_ISREG(mode):
        os.close(fd)
        kind = "a folder" if stat.S_ISDIR(mode) else "a device or a pipe"
        raise InputError(f"{path}: is {kind}, not a regular file")
    with os.fdopen(fd, "rb") as handle:
        try:
            data = handle.read(max_bytes + 1)
        except OSError as exc:
            raise InputError(f"{path}: cannot read the {what} ({_reason(exc)})") from None
    if len(data) > max_bytes:
        raise InputError(f"{path}: larger than {max_bytes} bytes: not a {what}")
    try:
        return data.decode(encoding)
    except UnicodeDecodeError as exc:
        raise InputError(f"{path}: not UTF-8 text (byte {exc.start}): not a {what}") from None


def _reason(exc: Exception) -> str:
    return getattr(exc, "strerror", None) or "a NUL character in the path"
