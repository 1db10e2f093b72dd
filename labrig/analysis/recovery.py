"""Recovering the file of a run whose process was killed.

The run writer keeps the file consistent on disk at every flush (SWMR), so a killed run
leaves a file holding everything up to its last flush, with two marks of the crash: the
superblock's "open for writing" flag, which makes HDF5 (and every tool built on it)
refuse to open the file normally, and the status "running" of the run and its current
repetition. ``recover_run`` clears the flag
(``labrig.recording.repair.clear_write_flag``, what ``h5clear -s`` does), records that the
run was cut short, and stores the analysis of what was recorded, so the file then reads
like any finished run. Each step says what it did; a file that needs nothing is left
untouched. A recover cut short before the analysis was stored leaves the file closed
and marked (its reason says labrig recovered it): the next recover stores the analysis.

A file a live run still writes looks just like a killed run's (the flag, "running"), so
recovery first takes the run file's lock, which a live run holds, and checks that no
other program has the file open: either refuses with nothing changed.
"""

from __future__ import annotations

from pathlib import Path

import h5py

from labrig.analysis.results import now_iso
from labrig.analysis.runfile import load_run
from labrig.recording.repair import clear_write_flag
from labrig.recording.run_file_lock import RunFileLock, refuse_if_open_elsewhere
from labrig.recording.run_layout import REASON_SIZE
from labrig.recording.run_reader import decode, open_run

# how a recovered run's reason begins (a recover's mark in the file)
RECOVERED = "the run stopped without closing its file (recovered by labrig"


def recover_run(path: Path, *, analyse: bool = True) -> list[str]:
    """Repair the run file at ``path``; returns one line per action taken."""
    refusal = "recover it once that has ended (nothing was changed)"
    with RunFileLock(path, "recover").acquire(refusal):
        record = load_run(path)  # InputError for anything that is not a readable run file
        refuse_if_open_elsewhere(path, refusal)
        return _recover(path, record, analyse)


def _has_analysis(path: Path) -> bool:
    with open_run(path) as run:
        return "entry/analysis" in run


def _recover(path: Path, record, analyse: bool) -> list[str]:
    lines = []
    reason = f"{RECOVERED} on {now_iso()})"
    # a recover cut short after the file was closed but before its analysis was stored
    owed = record.reason.startswith(RECOVERED) and not _has_analysis(path)
    if record.writer_flag_set:
        clear_write_flag(path)
        lines.append(f"{path}: cleared the writer's 'open for writing' flag")
    with h5py.File(path, "r+") as run:
        entry = run["entry"]
        if decode(entry["status"][()]) == "running":
            entry["status"][()] = b"aborted"
            entry["reason"][()] = reason.encode()[:REASON_SIZE]
            lines.append(f"{path}: run status running -> aborted")
        reps = entry["repetitions"]
        for i, status in enumerate(reps["status"][:]):
            if decode(status) == "running":
                reps["status"][i] = b"aborted"
                reps["reason"][i] = reason.encode()[:REASON_SIZE]
                lines.append(f"{path}: repetition {i + 1} running -> aborted")
    if not lines and not owed:
        lines.append(f"{path}: nothing to recover (closed by its writer, status {record.status})")
        return lines
    if analyse:
        from labrig.analysis.analyse import analyse_run

        result = analyse_run(path)
        complete = sum(r.status == "complete" for r in result.repetitions)
        lines.append(
            f"{path}: analysis stored ({complete} of {len(result.repetitions)} repetitions "
            f"complete, mean of {len(result.averaged)})"
        )
    return lines
