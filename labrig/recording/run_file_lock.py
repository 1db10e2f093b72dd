"""Who may write a run file: one process at a time, from before the file exists until it
is closed.

HDF5's own lock cannot do this. Opening in HDF5's create-or-truncate mode empties the
file before it asks for that lock (another program holding the file open found it
emptied), and a writer in single-writer/multiple-reader (SWMR) mode gives the lock up
so that readers can follow the file as it grows (a second run then wrote into the first
one's file).
So a run, and ``labrig recover``, take labrig's own locks, OS locks that the kernel
drops however the process ends (a killed run leaves no lock that holds):

- on the name, a sidecar ``RUN.h5.lock`` (``flock``; ``msvcrt.locking`` on Windows),
  from before the file exists: two runs told the same ``--out`` never both create it.
  It also says who holds the file. A killed run leaves at most the empty sidecar,
  which the next holder takes over and removes.
- on the file itself, a lock on one byte far past its end, taken as the run creates
  the file and held until it is closed. It belongs to the file (its device and inode),
  not to a name: a symlink, a hard link or a removed sidecar reaches the same lock.
  On Linux it is an open file description lock (``F_OFD_SETLK``): it belongs to the
  open file, so HDF5 opening and closing the same file in this process cannot drop it
  (a POSIX record lock elsewhere, which can), and it never meets HDF5's own ``flock``,
  which readers of a live file (``h5py`` with its defaults) must still get. Windows
  has the sidecar alone: its byte locks are mandatory, and it moves no open file.

Readers (``show``, ``watch``, the live page) take neither: they open a live file in
SWMR read mode.

Another program holding the file open (h5py, HDFView) holds HDF5's lock on the file
itself, shared for a reader; ``refuse_if_open_elsewhere`` asks for that lock before the
file is touched.
"""

from __future__ import annotations

import contextlib
import datetime as dt
import os
import stat
import struct
from pathlib import Path

from labrig.errors import InputError

try:
    import fcntl
except ImportError:  # Windows
    fcntl = None
    import msvcrt

# Windows locks a byte range, and a locked range cannot be read: the lock sits past the
# holder's line so that a refused process can still read who holds it
_WINDOWS_LOCK_OFFSET = 1 << 20
# the byte of the run file that is locked: past the end of any file, so no read meets it
_FILE_LOCK_OFFSET = 1 << 62


def lock_path(run_path: Path) -> Path:
    """The sidecar lock of a run file: ``RUN.h5.lock`` beside it."""
    return run_path.with_name(run_path.name + ".lock")


def _try_lock(fd: int) -> bool:
    """Lock ``fd`` without waiting; False if another process holds it."""
    try:
        if fcntl is not None:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        else:
            os.lseek(fd, _WINDOWS_LOCK_OFFSET, os.SEEK_SET)
            msvcrt.locking(fd, msvcrt.LK_NBLCK, 1)
    except OSError:
        return False
    return True


def _flock_struct(kind: int) -> bytes:
    """A ``struct flock`` for the one byte at ``_FILE_LOCK_OFFSET`` (pid 0, as an open
    file description lock asks)."""
    return struct.pack("hhqqi4x", kind, os.SEEK_SET, _FILE_LOCK_OFFSET, 1, 0)


def _lock_file(fd: int, writable: bool) -> bool:
    """Lock the file open at ``fd`` itself, without waiting; False if another holds it.
    A file open only for reading gets a shared lock, which a writer's refuses too."""
    if fcntl is None:  # Windows: the sidecar alone (Windows moves no open file anyway)
        return True
    try:
        if hasattr(fcntl, "F_OFD_SETLK"):
            kind = fcntl.F_WRLCK if writable else fcntl.F_RDLCK
            fcntl.fcntl(fd, fcntl.F_OFD_SETLK, _flock_struct(kind))
        else:  # a POSIX record lock: held while this process keeps every handle open
            mode = fcntl.LOCK_EX if writable else fcntl.LOCK_SH
            fcntl.lockf(fd, mode | fcntl.LOCK_NB, 1, _FILE_LOCK_OFFSET)
    except OSError:
        return False
    return True


def _file_locked_elsewhere(path: Path) -> bool:
    """Whether another open file holds the lock of the file at ``path`` (asked without
    taking it)."""
    if fcntl is None or not hasattr(fcntl, "F_OFD_GETLK"):
        # asking a POSIX record lock from this process would drop its own: the sidecar says
        return False
    try:
        fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK)
    except OSError:
        return False
    try:
        answer = fcntl.fcntl(fd, fcntl.F_OFD_GETLK, _flock_struct(fcntl.F_WRLCK))
        return struct.unpack("hhqqi4x", answer)[0] != fcntl.F_UNLCK
    except OSError:
        return False
    finally:
        os.close(fd)


class RunFileLock:
    """The locks of one run file, its name's (the sidecar) and the file's own, held by
    this process from ``acquire`` (or ``hold_new_file``) to ``release`` (also a context
    manager). ``purpose`` ("run", "recover", ...) is written into the sidecar so that a
    refused process can say who holds the file."""

    def __init__(self, run_path: str | Path, purpose: str) -> None:
        self.run_path = Path(run_path)
        self.path = lock_path(self.run_path)
        self.purpose = purpose
        self._fd: int | None = None
        self._file_fd: int | None = None  # the run file, locked itself

    def acquire(self, refusal: str) -> RunFileLock:
        """Take the lock of the name and, when the run file exists, of the file; or
        InputError: the run file, who holds it and ``refusal`` (what to do about it)."""
        self._acquire_name(refusal)
        nonblocking = getattr(os, "O_NONBLOCK", 0)  # a pipe's open would wait
        for flags in (os.O_RDWR, os.O_RDONLY):
            try:
                fd = os.open(self.run_path, flags | nonblocking)
            except OSError:
                continue
            if stat.S_ISREG(os.fstat(fd).st_mode):
                self._hold_file(fd, refusal, writable=flags == os.O_RDWR)
            else:
                os.close(fd)  # a device or a folder: its user says what is wrong
            break
        return self  # no file yet, or none that can be opened: its user says why

    def hold_new_file(self, made_fd: int, refusal: str) -> None:
        """Lock the run file that ``made_fd`` (HDF5's handle, under the name's lock) has
        just created, through that same open file: no path is looked up again, so what
        is locked is the file that was made, whatever the path names meanwhile."""
        self._hold_file(os.dup(made_fd), refusal, writable=True)

    def file_identity(self) -> tuple[int, int]:
        """(device, inode) of the file ``hold_new_file`` locked: what the path must still
        name for the run to remove it."""
        held = os.fstat(self._file_fd)
        return held.st_dev, held.st_ino

    def _hold_file(self, fd: int, refusal: str, *, writable: bool) -> None:
        if not _lock_file(fd, writable):
            os.close(fd)
            self.release()
            raise InputError(
                f"{self.run_path}: a labrig process holds this file (a run writing it, or a "
                f"recover), under this name or another; {refusal}"
            )
        if self._file_fd is not None:
            os.close(self._file_fd)
        self._file_fd = fd

    def _acquire_name(self, refusal: str) -> None:
        while True:
            try:
                fd = os.open(self.path, os.O_RDWR | os.O_CREAT, 0o644)
            except OSError as exc:
                raise InputError(
                    f"{self.run_path}: cannot create its lock file {self.path} ({exc.strerror})"
                ) from None
            if not _try_lock(fd):
                os.close(fd)
                raise InputError(f"{self.run_path}: {self._holder()}; {refusal}")
            # the previous holder removes the sidecar as it lets go: a lock taken on a
            # sidecar that is no longer at the path would lock nothing
            try:
                same = os.path.samestat(os.fstat(fd), os.stat(self.path))
            except FileNotFoundError:
                same = False
            if same:
                break
            os.close(fd)
        os.ftruncate(fd, 0)
        os.lseek(fd, 0, os.SEEK_SET)  # Windows' lock moved the position
        os.write(fd, f"{os.getpid()} {self.purpose}\n".encode())
        self._fd = fd

    def _holder(self) -> str:
        """Who holds the lock, as the holder wrote it."""
        try:
            words = self.path.read_text(encoding="utf-8", errors="replace").split()
        except OSError:
            words = []
        if len(words) == 2 and words[0].isdigit():
            pid, purpose = words
            doing = "writing" if purpose == "run" else f"using ({purpose})"
            return f"a labrig process (pid {pid}) is {doing} this file"
        return f"another labrig process holds its lock ({self.path})"

    def release(self) -> None:
        """Let go (idempotent): the file's lock, then the sidecar, removed while still
        locked, then closed."""
        if self._file_fd is not None:
            fd, self._file_fd = self._file_fd, None
            os.close(fd)
        if self._fd is None:
            return
        fd, self._fd = self._fd, None
        if fcntl is not None:
            self.path.unlink(missing_ok=True)
            os.close(fd)
        else:  # Windows removes no file that is open
            os.close(fd)
            # another process that opened it meanwhile takes it over
            with contextlib.suppress(PermissionError):
                self.path.unlink(missing_ok=True)

    def __enter__(self) -> RunFileLock:
        return self

    def __exit__(self, *exc_info) -> None:
        self.release()


def held_by_a_process(run_path: Path) -> bool:
    """Whether a live process holds ``run_path``'s lock, of the file itself (reached by
    any name) or of its name (a run writing it, or a recover), asked without creating or
    writing anything: a killed run's locks went with it, so its file reads as not held."""
    if _file_locked_elsewhere(Path(run_path)):
        return True
    try:
        fd = os.open(lock_path(Path(run_path)), os.O_RDWR)
    except OSError:
        return False
    try:
        if not _try_lock(fd):
            return True
        if fcntl is not None:
            fcntl.flock(fd, fcntl.LOCK_UN)
        else:
            os.lseek(fd, _WINDOWS_LOCK_OFFSET, os.SEEK_SET)
            msvcrt.locking(fd, msvcrt.LK_UNLCK, 1)
        return False
    finally:
        os.close(fd)


def reserve_new_name(path: Path) -> bool:
    """Claim ``path`` as a new run's name; False if it is taken. Its sidecar lock is
    created here, only if absent, so two processes asking at once never both get the
    name; neither the file nor its video may be there. The run's writer takes the
    sidecar over (and removes it with its lock); ``drop_reservation`` removes it when
    no run came to write."""
    try:
        os.close(os.open(lock_path(path), os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o644))
    except FileExistsError:
        return False
    except OSError as exc:
        raise InputError(f"{path}: cannot reserve the run file ({exc.strerror})") from None
    if path.exists() or path.with_suffix(".avi").exists():
        lock_path(path).unlink()
        return False
    return True


def drop_reservation(path: Path) -> None:
    """Remove the sidecar ``reserve_new_name`` made, when no process holds it (a run
    that wrote the file removed it already)."""
    if not held_by_a_process(path):
        lock_path(path).unlink(missing_ok=True)


def refuse_if_open_elsewhere(path: Path, refusal: str) -> None:
    """InputError if another program has the HDF5 file at ``path`` open with HDF5's
    file locking (its default): a reader holds a shared lock, so an exclusive one is
    refused. Asked for and let go at once: HDF5 in this process must get it later."""
    if fcntl is None:  # Windows refuses to move or replace an open file: told where it happens
        return
    fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK)
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except BlockingIOError:
        raise InputError(
            f"{path}: open in another program (an HDF5 viewer or a script holds it); {refusal}"
        ) from None
    finally:
        os.close(fd)


def replaced_path(path: Path, stamp: str) -> Path:
    """Where ``--overwrite`` moves an old run file: ``RUN.replaced-<stamp>.h5``, with a
    counter if that is taken."""
    candidate = path.with_name(f"{path.stem}.replaced-{stamp}{path.suffix}")
    counter = 2
    # lexists: a link there, even a dangling one, is a name taken (rename replaces it)
    while os.path.lexists(candidate) or os.path.lexists(candidate.with_suffix(".avi")):
        candidate = path.with_name(f"{path.stem}.replaced-{stamp}-{counter}{path.suffix}")
        counter += 1
    return candidate


def check_run_name(path: Path) -> None:
    """InputError unless ``path`` can name a run file: plain text, and not a name of
    the run's other outputs (its video ``RUN.avi``, its lock ``RUN.h5.lock``), which
    would then be one file."""
    from labrig.user_files import check_shown_name

    check_shown_name(path, "--out")
    if path.suffix.lower() in (".avi", ".lock"):
        raise InputError(
            f"{path}: a run file's name cannot end in {path.suffix}: the run's video is "
            "RUN.avi and its lock RUN.h5.lock beside it; give a name ending in .h5"
        )


def claim_out_path(path: Path, *, overwrite: bool) -> list[str]:
    """Make ``path`` free for a new run before anything moves; one line per file moved.

    An existing file is refused unless ``overwrite``, which moves it (and its video,
    ``RUN.avi``) aside, never deletes. A file another labrig process writes, or another
    program holds open, is refused either way. The run's writer takes the lock again
    and creates the file only if it is still absent: a run started meanwhile onto the
    same path makes this one stop with one line, and nothing is lost.
    """
    check_run_name(path)
    video = path.with_suffix(".avi")  # where the run records its video, if it does
    advice = "choose another --out"
    try:
        there = [p for p in (path, video) if p.exists() or p.is_symlink()]
    except OSError as exc:  # a name too long, a folder that cannot be searched
        raise InputError(f"{path}: not a usable run file name ({exc.strerror})") from None
    if not there:
        return []
    with RunFileLock(path, "overwrite").acquire(advice):
        if any(not p.is_file() for p in there):
            raise InputError(f"{there[0]}: exists and is not a regular file; {advice}")
        if not overwrite:
            what = "a run file" if there[0] == path else "a run's video"
            raise InputError(
                f"{there[0]}: {what} is already there; {advice}, or --overwrite to move it "
                "aside first (it is never deleted)"
            )
        if path in there:
            refuse_if_open_elsewhere(path, f"close it there, or {advice}")
        target = replaced_path(path, dt.datetime.now().strftime("%Y%m%d-%H%M%S"))
        moved = [_move(p, target.with_suffix(p.suffix)) for p in there]
        if (
            path in there
            and video in there
            and not _rename_video_in(target, target.with_suffix(".avi").name)
        ):
            moved.append(f"{target} still names its video {video.name}: not a run file")
        return moved


def _move(source: Path, target: Path) -> str:
    try:
        os.rename(source, target)
    except OSError as exc:
        raise InputError(f"{source}: cannot be moved aside to {target} ({exc.strerror})") from None
    return f"moved the old {source} to {target}"


def _rename_video_in(run_path: Path, video_name: str) -> bool:
    """Point the moved run file at its moved video (``/entry/video@file``); False if
    the file cannot be opened to do so."""
    import h5py

    try:
        with h5py.File(run_path, "r+") as run:
            if "entry/video" in run:
                run["entry/video"].attrs["file"] = video_name
    except OSError:
        return False
    return True
