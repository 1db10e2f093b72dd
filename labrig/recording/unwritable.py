"""Letting go of an HDF5 file that cannot be written (a full disk, a file size limit).

Every close of such a file fails: h5py prints a traceback for each object of it freed
(the same failure again), and HDF5's own clean-up at exit tries the close once more and
crashes the process (SIGSEGV: h5py's error handler is gone by then). So its handles are
kept for the life of the process, h5py's frees are kept quiet, and the process ends
before HDF5's clean-up with the error exit status; the OS closes the file. On disk the
file is as its last successful write left it.
"""

from __future__ import annotations

import atexit
import contextlib
import logging
import os
import shutil
import sys
from pathlib import Path

from labrig.errors import InputError

log = logging.getLogger(__name__)


def abandon(*handles) -> None:
    """Never free ``handles`` (h5py identifiers of the unwritable file) and end the
    process before HDF5 cleans up."""
    quiet_h5py_frees()
    _keep_for_the_process(*handles)
    if not getattr(abandon, "registered", False):
        atexit.register(_end_before_hdf5_cleans_up)
        abandon.registered = True


def room_to_write(path: Path, need_bytes: int, what: str) -> None:
    """InputError (nothing written) unless the disk and the process's file size limit
    leave ``need_bytes`` more to the file at ``path``: a write that fails half-way
    through HDF5's metadata can leave the whole file unreadable."""
    free = shutil.disk_usage(path.parent).free
    if free < need_bytes:
        raise InputError(
            f"{path}: {what} not stored: the disk has {free} bytes free, {need_bytes} are "
            "needed (the file is unchanged)"
        )
    try:
        import resource

        limit = resource.getrlimit(resource.RLIMIT_FSIZE)[0]
    except (ImportError, OSError, ValueError):
        return
    if limit != resource.RLIM_INFINITY and os.stat(path).st_size + need_bytes > limit:
        raise InputError(
            f"{path}: {what} not stored: the process may not write files over {limit} "
            "bytes (ulimit -f; the file is unchanged)"
        )


def _end_before_hdf5_cleans_up() -> None:
    """The output flushed, the process ends with the error exit status (a file was
    left as far as it could be written)."""
    logging.shutdown()
    for stream in (sys.stdout, sys.stderr):
        with contextlib.suppress(Exception):
            stream.flush()
    os._exit(1)


def _keep_for_the_process(*handles) -> None:
    import ctypes

    for handle in handles:
        ctypes.pythonapi.Py_IncRef(ctypes.py_object(handle))


def quiet_h5py_frees() -> None:
    """Say nothing of h5py objects freed once a file could not be written: each
    would print a traceback of the same failure (logged instead)."""
    if getattr(sys.unraisablehook, "labrig_quiet_h5py", False):
        return
    previous = sys.unraisablehook

    def hook(unraisable) -> None:
        where = unraisable.object
        if isinstance(where, str) and where.startswith("h5py."):
            log.debug("freeing an object of an unwritable HDF5 file: %s", unraisable.exc_value)
            return
        previous(unraisable)

    hook.labrig_quiet_h5py = True
    sys.unraisablehook = hook
