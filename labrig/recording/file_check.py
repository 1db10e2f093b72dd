"""Reading an HDF5 file nobody vouches for: walked first by a child process, watched.

libhdf5 trusts the bytes it reads. A run file with a few bytes zeroed or flipped (a
bad copy, a failing stick, a truncated transfer) can send it into a loop that never
returns while it holds Python's lock, so neither a timeout nor Ctrl-C reaches the
reader (2 kB zeroed at byte 4000 of a run file kept ``labrig show`` at 100 % CPU for
minutes), or into a crash. So before a reader's own process opens such a file, a child
process opens it the same way and reads every object in it: each link, each
attribute, each dataset in slices, saying after each that it is still going. A child
silent for ``STALL_S``, or one that dies, condemns the file in one line, and the
reader's process never touches it. The child also refuses what no run file holds and
a reader would read whole: a text over ``MAX_TEXT_BYTES``, a link to another file;
its memory is capped too. An array of more than ``MAX_DATASET_VALUES`` values is read
only in its first slice: no reader reads one whole (``run_reader.read_values``).

libhdf5 reads the same bytes the same way twice, so what the child read to its end the
reader can read. A file this process wrote (``vouch_for``) or walked already, unchanged
since (same inode, size and modification time), is not walked again.
"""

from __future__ import annotations

import os
import queue
import subprocess
import sys
import threading
from pathlib import Path

from labrig.errors import InputError
from labrig.recording.run_layout import MAX_DATASET_VALUES
from labrig.user_files import HDF5_SIGNATURE

# a protocol file is capped at 1 MB (labrig.user_files): so is any text a run stores
MAX_TEXT_BYTES = 1_000_000
# no object of a sound file takes libhdf5 a second; a stuck one never ends
STALL_S = 3.0
# the child's interpreter and h5py load before the first object (no file is read yet)
STARTUP_S = 60.0
# what the child may map: h5py and numpy take ~120 MB, a slice 8 MB, a text 1 MB
CHILD_MEMORY_BYTES = 1 << 31
# bytes read per slice of a large dataset
SLICE_BYTES = 8 << 20

_verdicts: dict[tuple[int, int, int, int], str] = {}  # file identity -> "" or the error
_verdicts_lock = threading.Lock()


def _identity(path: Path) -> tuple[int, int, int, int] | None:
    try:
        st = os.stat(path)
    except OSError:
        return None
    return st.st_dev, st.st_ino, st.st_size, st.st_mtime_ns


def vouch_for(path: str | Path) -> None:
    """Trust the file at ``path`` as it is now: this process wrote it."""
    key = _identity(Path(path))
    if key is not None:
        with _verdicts_lock:
            _verdicts[key] = ""


def check_file(path: str | Path) -> None:
    """InputError (one line) unless the HDF5 file at ``path`` reads to its end within
    the bounds above; walked once per version of the file."""
    path = Path(path)
    error = check_files([path])[path]
    if error:
        raise InputError(error)


def superblock_facts(path: Path) -> tuple[int, int, int] | None:
    """(superblock version, consistency flags, end-of-file address) of an HDF5 file with
    a version 2 or 3 superblock, or None when the header is not one of those.

    Read directly from the header because HDF5 refuses to open exactly the files whose
    diagnosis needs these numbers (a truncated file, one still flagged open).
    """
    with open(path, "rb") as handle:
        header = handle.read(48)
    if len(header) < 12 or header[:8] != HDF5_SIGNATURE or header[8] not in (2, 3):
        return None
    offsets = header[9]
    eof_at = 12 + 2 * offsets  # after base address and superblock-extension address
    if len(header) < eof_at + offsets:
        return None
    eof = int.from_bytes(header[eof_at : eof_at + offsets], "little")
    return header[8], header[11], eof


def truncation(path: Path) -> str:
    """Why the file is cut short ("" if its header's end-of-file address is there): read
    from the header, before libhdf5 (which loops on some such files) is let near it."""
    try:
        facts = superblock_facts(path)
        size = os.stat(path).st_size
    except OSError:
        return ""
    if facts is None or facts[2] <= size:
        return ""
    return (
        f"{path}: truncated: {size} of the {facts[2]} bytes its header announces are "
        "present; the end of the file is missing (copy it again from where it was "
        "recorded)"
    )


def unopenable(path: Path, error: str) -> str:
    """Why libhdf5 could not open the file, more clearly than its ``error`` where the
    header tells: no HDF5 signature at the start, or cut short."""
    try:
        size = os.stat(path).st_size
        with open(path, "rb") as handle:
            signature = handle.read(8)
    except OSError:
        return error
    if signature != HDF5_SIGNATURE:
        return (
            f"{path}: not an HDF5 file (no HDF5 signature at the start; {size} bytes); "
            "a labrig run file is written by `labrig run`"
        )
    return truncation(path) or error


def check_files(paths: list[Path]) -> dict[Path, str]:
    """Each file's verdict ("" or its one-line error), the unknown ones walked by one
    child in turn (a fresh child after one that got stuck or died)."""
    verdicts: dict[Path, str] = {}
    todo: list[tuple[Path, tuple]] = []
    for path in paths:
        key = _identity(path)
        with _verdicts_lock:
            known = _verdicts.get(key) if key is not None else None
        if known is not None:
            verdicts[path] = known
        elif cut := truncation(path):
            verdicts[path] = cut
        else:
            todo.append((path, key))
    while todo:
        done = _walk_in_child([path for path, _ in todo])
        for (path, key), verdict in zip(todo, done, strict=False):
            verdicts[path] = verdict
            if key is not None and _identity(path) == key:
                with _verdicts_lock:
                    _verdicts[key] = verdict
        todo = todo[len(done) :]
    return verdicts


def _walk_in_child(paths: list[Path]) -> list[str]:
    """The verdicts of the first files of ``paths`` the child could judge (at least
    one: the file it was on when it got stuck or died is condemned)."""
    env = dict(os.environ, OPENBLAS_NUM_THREADS="1", OMP_NUM_THREADS="1")
    package_root = str(Path(__file__).resolve().parents[2])
    env["PYTHONPATH"] = os.pathsep.join(filter(None, [package_root, env.get("PYTHONPATH")]))
    child = subprocess.Popen(
        _child_command(paths),
        stdin=subprocess.DEVNULL,
        stdout=subprocess.PIPE,
        stderr=subprocess.DEVNULL,
        env=env,
    )
    # the child's lines, read by a thread: a wait on a queue has a timeout and lets
    # Ctrl-C through on every platform (select takes no pipe on Windows)
    lines: queue.Queue[bytes | None] = queue.Queue()

    def read_lines() -> None:
        for line in child.stdout:
            lines.put(line)
        lines.put(None)

    reader = threading.Thread(target=read_lines, name="file check", daemon=True)
    reader.start()
    verdicts: list[str] = []
    try:
        limit_s = STARTUP_S
        while len(verdicts) < len(paths):
            try:
                line = lines.get(timeout=limit_s)
            except queue.Empty:
                verdicts.append(_stuck(paths[len(verdicts)], limit_s))
                break
            if line is None:  # the child died on this file
                verdicts.append(_died(paths[len(verdicts)], child.wait()))
                break
            if line.startswith(b"="):
                verdicts.append(line[1:].rstrip(b"\n").decode("utf-8", "replace"))
            limit_s = STALL_S
    finally:
        if child.poll() is None:
            child.kill()
        child.wait()
        reader.join(timeout=5.0)  # at the end of the pipe: the child is gone
        if not reader.is_alive():
            child.stdout.close()
    return verdicts


def _child_command(paths: list[Path]) -> list[str]:
    return [sys.executable, "-m", "labrig.recording.file_check", *map(str, paths)]


def _stuck(path: Path, waited_s: float) -> str:
    return (
        f"{path}: damaged: libhdf5 was still reading one part of it after {waited_s:g} s "
        "(a sound run file takes it milliseconds); not read"
    )


def _died(path: Path, returncode: int) -> str:
    how = f"signal {-returncode}" if returncode < 0 else f"exit {returncode}"
    return f"{path}: damaged: reading it crashed libhdf5 ({how}); not read"


# --- the child ------------------------------------------------------------------------
def _serve(paths: list[str]) -> None:
    """Walk each file, printing a line per object read ('.') and its verdict
    ('=' and "" or the error)."""
    try:
        import resource
    except ImportError:  # Windows: no cap on the child's memory
        pass
    else:
        resource.setrlimit(resource.RLIMIT_AS, (CHILD_MEMORY_BYTES, CHILD_MEMORY_BYTES))
    import h5py  # noqa: F401  (loaded before the first line: startup is not a stall)

    out = sys.stdout.buffer
    for path in paths:
        try:
            verdict = _walk(Path(path), lambda: (out.write(b".\n"), out.flush()))
        except MemoryError:
            verdict = f"{path}: damaged: reading it asks for more memory than a run file needs"
        out.write(b"=" + verdict.replace("\n", " ").encode() + b"\n")
        out.flush()


def _walk(path: Path, beat) -> str:
    import h5py

    try:
        run = h5py.File(path, "r", locking=False)
    except OSError as plain_error:
        try:
            run = h5py.File(path, "r", libver="latest", swmr=True, locking=False)
        except OSError:
            return unopenable(path, f"{path}: not a readable HDF5 file ({plain_error})")
    where = ""
    try:
        with run:
            for where, link in _links(run, beat):
                if not isinstance(link, h5py.HardLink):
                    return f"{path}: {_named(where)} is a link elsewhere; a run file holds none"
            for where, obj in _objects(run):
                for name in obj.attrs:
                    obj.attrs[name]
                beat()
                if isinstance(obj, h5py.Dataset):
                    problem = _read_dataset(obj, beat)
                    if problem:
                        return f"{path}: {_named(where)} {problem}"
    except (OSError, RuntimeError, ValueError, KeyError, TypeError, UnicodeError) as exc:
        return f"{path}: damaged: {_named(where)} cannot be read ({type(exc).__name__}: {exc})"
    return ""


def _links(run, beat):
    """Every link below the root, with its name."""
    found = []

    def seen(name, link) -> None:
        found.append((name, link))
        beat()

    run.visititems_links(seen)
    return found


def _objects(run):
    found = [("/", run)]

    def seen(name, obj) -> None:
        found.append((name, obj))

    run.visititems(seen)
    return found


def _read_dataset(dataset, beat) -> str:
    """Why the dataset is refused, or "" once it was read to its end."""
    if dataset.is_virtual or dataset.external:
        return "keeps its values in other files; a run file's are in it"
    if dataset.dtype.kind == "O":  # variable-length text: sizes known once read
        values = dataset[()]
        items = values.ravel() if hasattr(values, "ravel") else [values]
        size = sum(len(item) for item in items if isinstance(item, bytes | str))
        if size > MAX_TEXT_BYTES:
            return (
                f"holds a text of {size} bytes, more than the {MAX_TEXT_BYTES} a run "
                "file's text may hold"
            )
        return ""
    if dataset.ndim == 0:
        dataset[()]
        return ""
    row_bytes = max(1, dataset.size // max(1, dataset.shape[0])) * dataset.dtype.itemsize
    step = max(1, SLICE_BYTES // row_bytes)
    rows = dataset.shape[0] if dataset.size <= MAX_DATASET_VALUES else step
    for start in range(0, rows, step):
        dataset[start : start + step]
        beat()
    return ""


def _named(where: str) -> str:
    """An object's name as the file spells it, when it is short, plain text; the file's
    bytes are not echoed otherwise."""
    name = "/" + where.lstrip("/")
    return name if len(name) <= 120 and name.isascii() and name.isprintable() else "an object"


if __name__ == "__main__":
    _serve(sys.argv[1:])
