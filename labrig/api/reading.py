"""Opening a run file without disturbing its writer.

The Python API only reads: files are opened with mode ``"r"``, in HDF5's SWMR read mode
where the file is still being written (or was left by a killed writer), and always
without HDF5's file lock (``locking=False``). A reader holding that lock would make the
runner's own reopening fail when the run ends (it stores the analysis), so the API never
takes it; SWMR itself needs no lock on the reader's side. Nothing here repairs a file:
``labrig recover`` does that, on purpose, from the command line.
"""

from __future__ import annotations

from pathlib import Path

import h5py

from labrig.analysis.runfile import open_checked, writer_flag_set
from labrig.recording.run_file_lock import held_by_a_process
from labrig.recording.run_reader import open_run


def open_readonly(path: Path) -> h5py.File:
    """``path`` opened for reading, never locked, never written."""
    return open_run(path, locking=False)


def open_run_file(path: Path) -> h5py.File:
    """A labrig run file opened read-only and checked (``/entry`` present); InputError
    naming what is wrong otherwise."""
    return open_checked(path, open_readonly)


def writer_state(path: Path, status: str) -> tuple[bool, bool]:
    """(writer_open, live) of a run file whose recorded status is ``status``.

    ``writer_open``: the file still carries its writer's "open for writing" flag (it is
    being recorded, or its writer was killed). ``live``: flagged open, status
    ``running``, and a process holds the run's lock: a writer is recording it now.
    """
    flagged = writer_flag_set(path)
    return flagged, flagged and status == "running" and held_by_a_process(path)
