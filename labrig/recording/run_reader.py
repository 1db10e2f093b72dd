"""Reading a run file back: opening it (also one a killed writer left), its logs as
plain arrays, and the statuses of its repetitions."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import h5py
import numpy as np

from labrig.errors import InputError
from labrig.recording.file_check import check_file
from labrig.recording.run_layout import MAX_DATASET_VALUES, repetition_name


@dataclass(frozen=True)
class LogSeries:
    """One NXlog read back: its time axis and fields, as plain arrays."""

    time_s: np.ndarray
    fields: dict[str, np.ndarray]

    def __len__(self) -> int:
        return len(self.time_s)


def open_run(path: str | Path, *, locking: bool = True) -> h5py.File:
    """Open a run file for reading, even one whose writer was killed.

    A file left open by a killed SWMR writer refuses a plain open; SWMR read mode
    reads it as it was at the writer's last flush. ``locking=False`` leaves HDF5's file
    lock alone: a reader that holds it would make the runner's own reopening fail when
    the run ends (the Python API reads live runs so).
    """
    path = Path(path)
    if not path.exists():
        raise InputError(f"{path}: no such file")
    if not path.is_file():  # HDF5 would wait forever on a pipe's open
        raise InputError(f"{path}: not a regular file (a folder, a device or a pipe)")
    check_file(path)  # a damaged file is walked by a watched child first
    # HDF5's default, not an explicit True: another handle of this process on the file
    # (the writer's) must have been opened with the same locking flags
    lock = {} if locking else {"locking": False}
    try:
        return h5py.File(path, "r", **lock)
    except OSError as plain_error:
        try:
            return h5py.File(path, "r", libver="latest", swmr=True, **lock)
        except OSError:
            raise InputError(f"{path}: not a readable HDF5 file ({plain_error})") from None


def read_values(dataset: h5py.Dataset, where: str):
    """A dataset's whole value; InputError, not MemoryError, for one too large."""
    if dataset.size > MAX_DATASET_VALUES:
        raise InputError(
            f"{where}: {dataset.name} holds {dataset.size} values, more than the "
            f"{MAX_DATASET_VALUES} of any run of this rig"
        )
    try:
        return dataset[()]
    except MemoryError:
        raise InputError(
            f"{where}: {dataset.name}: {dataset.size} values do not fit in memory"
        ) from None


def read_rows(dataset: h5py.Dataset, first: int, last: int, where) -> np.ndarray:
    """Rows ``first`` to ``last`` of a dataset; InputError for more than any run holds."""
    if last - first > MAX_DATASET_VALUES:
        raise InputError(
            f"{where}: {dataset.name}: {last - first} rows asked for, more than the "
            f"{MAX_DATASET_VALUES} of any run of this rig (ask for a window: start_s, stop_s)"
        )
    return dataset[first:last]


def read_log(run: h5py.File, repetition: int, log: str) -> LogSeries:
    """Read one repetition's NXlog; InputError naming what is missing if absent."""
    where = f"entry/repetitions/{repetition_name(repetition)}/{log}"
    if where not in run:
        raise InputError(f"{run.filename}: missing {where}")
    group = run[where]
    fields = {name: read_values(group[name], run.filename) for name in group if name != "time"}
    return LogSeries(read_values(group["time"], run.filename), fields)


def repetition_statuses(run: h5py.File) -> list[tuple[str, str]]:
    reps = run["entry/repetitions"]
    return [
        (status.decode(), reason.decode())
        for status, reason in zip(reps["status"][:], reps["reason"][:], strict=True)
    ]


def decode(value) -> str:
    """A fixed-size byte string from the file, as text."""
    return value.decode() if isinstance(value, bytes) else str(value)
