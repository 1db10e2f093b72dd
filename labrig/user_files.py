"""Files a person named: reading one (a protocol, a rig file, a measured curve) as a
regular file of bounded size, as text; and checking a path a command is told to write
(a CSV, a plot) before anything is written there.

A path is whatever a protocol says, so it may name ``/dev/zero`` (read forever until
memory runs out), a FIFO (an open that waits for a writer forever) or a folder. The file
is opened without waiting (``O_NONBLOCK``: a FIFO's open returns at once) and checked on
the open descriptor, so what is checked is what is read.
"""

from __future__ import annotations

import os
import stat
import unicodedata
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


# a name that would show other than it is: line breaks and other controls, and the
# marks that reorder text (U+202E shows "run\u202eh5.exe" as "runexe.5h")
_BIDI_MARKS = set("\u061c\u200e\u200f\u202a\u202b\u202c\u202d\u202e\u2066\u2067\u2068\u2069")
HDF5_SIGNATURE = b"\x89HDF\r\n\x1a\n"


def check_shown_name(path: Path, option: str) -> None:
    """InputError if ``path`` holds a control character or a text-direction mark: a
    file name a terminal, a listing or a log would show as something else."""
    for index, char in enumerate(str(path), 1):
        if char in _BIDI_MARKS or unicodedata.category(char) == "Cc":
            raise InputError(
                f"{option} {str(path)!a}: character {index} is a control or a "
                f"text-direction mark (U+{ord(char):04X}); give a plain name"
            )


def check_output_path(
    path: Path, option: str, *, overwrite: bool | None = False, own_kind: str | None = None
) -> None:
    """Before a command writes a new file at ``path`` (``option`` names it: "--csv",
    "-o"): InputError (one line, nothing written) if the name is not plain text, its
    folder cannot take the file, or the path holds a run file or any other HDF5 file
    this command did not make (``own_kind``: the root's ``kind`` attribute of its own
    HDF5 files, which it may replace); ``overwrite`` lets such a file go, never one a
    labrig process is writing (None: the command has no ``--overwrite``). So a CSV or a
    plot aimed at a run file by a slip of the shell's completion replaces nothing."""
    from labrig.recording.run_file_lock import held_by_a_process

    check_shown_name(path, option)
    folder = path.parent
    if not folder.is_dir():
        raise InputError(f"{option} {path}: the folder {folder} does not exist")
    if held_by_a_process(path):
        raise InputError(f"{option} {path}: a labrig run is writing this file; choose another name")
    if not os.access(folder, os.W_OK) and not os.access(path, os.W_OK):
        raise InputError(f"{option} {path}: the folder {folder} is read-only here")
    try:
        if not stat.S_ISREG(os.stat(path).st_mode):
            return  # a device (/dev/null) or a pipe: written as it is
        with open(path, "rb") as handle:
            if handle.read(8) != HDF5_SIGNATURE:
                return
    except OSError:  # absent, a dangling link, no permission: the write says
        return
    if overwrite or (own_kind is not None and _hdf5_kind(path) == own_kind):
        return
    raise InputError(
        f"{option} {path}: holds an HDF5 file (a run file?), which this command never "
        "writes over; choose another name"
        + (", or --overwrite to replace it" if overwrite is False else "")
    )


def _hdf5_kind(path: Path) -> str | None:
    """The root's ``kind`` attribute of the HDF5 file at ``path`` (read after the
    file was walked by a watched child: it may be damaged)."""
    from labrig.recording.file_check import check_files

    if check_files([path])[path]:
        return None
    import h5py

    with h5py.File(path, "r", locking=False) as h5:
        kind = h5.attrs.get("kind")
    return kind.decode() if isinstance(kind, bytes) else kind
