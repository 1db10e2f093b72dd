"""Follow a run file that another process is recording, for ``labrig watch``.

The writer (``labrig.recording.run_writer.RunWriter``) creates the whole layout, then switches the
file to HDF5's SWMR mode and only appends. A reader opened with ``swmr=True`` sees the
file as of the writer's last flush (at most half a second old); each poll refreshes the
datasets and feeds only the rows it has not seen to the same ``LiveState.tap`` the
runner feeds in ``labrig run --live``, so the page and its state are the same. The
rows of one log are fed only as far as every field of it has been written.

The file has no step label, so the step is told from what the pump is doing and the
time left from the protocol's plan (stored in the file) and the time since the first
repetition started. Once the file's status is final the follower feeds the rest,
reports the end and closes the file, so the writer's analysis can open it again.
"""

from __future__ import annotations

import time
from pathlib import Path

import h5py
import numpy as np

from labrig.config.protocol import Protocol, parse_protocol, plan
from labrig.errors import InputError
from labrig.live.state import FINAL_STATUSES, LiveState, Step
from labrig.recording.file_check import check_file
from labrig.recording.run_layout import LOG_FIELDS, repetition_name
from labrig.recording.run_reader import decode

POLL_S = 0.25
STEP_BY_PUMP_STATE = {"infusing": "infuse", "withdrawing": "withdraw", "stalled": "stalled"}


def open_growing(path: Path, wait_s: float = 5.0) -> h5py.File:
    """The run file opened for reading while another process may be writing it. A
    file just created is locked until its writer switches to SWMR: tried for
    ``wait_s``."""
    if not path.exists():
        raise InputError(f"{path}: no such file")
    if not path.is_file():  # HDF5 would wait forever on a pipe's open
        raise InputError(f"{path}: not a regular file (a folder, a device or a pipe)")
    deadline = time.monotonic() + wait_s
    checked = False
    while True:
        try:
            if not checked:  # a damaged file is walked by a watched child first, once
                check_file(path)
                checked = True
            # no file lock: the writer reopens the file for its analysis once the run
            # has ended, and must not find it locked by a reader that has not yet seen
            # the end (SWMR itself needs no lock on the reader's side)
            return h5py.File(path, "r", libver="latest", swmr=True, locking=False)
        except (OSError, InputError) as exc:
            if time.monotonic() > deadline:
                if isinstance(exc, InputError):
                    raise
                raise InputError(
                    f"{path}: cannot be read while it is recorded ({exc}); a labrig run "
                    "file is written by `labrig run`"
                ) from None
        time.sleep(POLL_S)


def protocol_of(run: h5py.File) -> tuple[Protocol, str]:
    """The protocol stored in the file and the run's title."""
    where = f"{run.filename}:/entry/protocol"
    if "entry/protocol" not in run:
        raise InputError(f"{run.filename}: not a labrig run file (no /entry/protocol)")
    protocol = parse_protocol(decode(run["entry/protocol"][()]), where)
    return protocol, decode(run["entry/title"][()]) if "entry/title" in run else protocol.name


class FileFollower:
    """Feeds ``state`` from the growing file ``run`` until its status is final."""

    def __init__(self, run: h5py.File, state: LiveState, protocol: Protocol) -> None:
        self.run = run
        self.state = state
        self.duration_s = plan(protocol).duration_s
        self._rows: dict[tuple[int, str], int] = {}
        self._t_first: float | None = None
        self._t_last: float | None = None
        self._pump_state = ""
        self._fed_repetition = 0  # the latest repetition with samples fed

    def follow(self) -> str:
        """Poll until the run ends; returns its final status."""
        while True:
            status = self.poll()
            if status in FINAL_STATUSES:
                return status
            time.sleep(POLL_S)

    def poll(self) -> str:
        """Feed what is new; the file's status (after the rest is fed when final)."""
        entry = self.run["entry"]
        entry["status"].refresh()
        status = decode(entry["status"][()])
        reps = entry["repetitions"]
        reps["status"].refresh()
        reps["t_start"].refresh()
        rep_status = [decode(s) for s in reps["status"][:]]
        for index in range(1, len(rep_status) + 1):
            group = reps[repetition_name(index)]
            for log in LOG_FIELDS:
                if log in group:
                    self._feed(index, log, group[log])
        self._report_step(rep_status, reps["t_start"][:])
        if status in FINAL_STATUSES:
            entry["reason"].refresh()
            self.state.finish(status, decode(entry["reason"][()]))
            self.run.close()
        return status

    def _feed(self, repetition: int, log: str, group: h5py.Group) -> None:
        datasets = [group[name] for name in LOG_FIELDS[log] if name in group]
        for dataset in datasets:
            dataset.refresh()
        n = min(d.shape[0] for d in datasets)
        start = self._rows.get((repetition, log), 0)
        if n <= start:
            return
        columns = {name: group[name][start:n] for name in LOG_FIELDS[log] if name in group}
        self._rows[(repetition, log)] = n
        t = columns["time"]
        self._t_first = float(t[0]) if self._t_first is None else self._t_first
        self._t_last = max(self._t_last or float(t[-1]), float(t[-1]))
        if log == "pump":
            self._pump_state = decode(columns["state"][-1])
        self._fed_repetition = max(self._fed_repetition, repetition)
        self._under_way()  # before the samples reach the page: never data and "starting"
        self.state.tap(repetition, log, columns)

    def _report_step(self, rep_status: list[str], t_start: np.ndarray) -> None:
        running = [i + 1 for i, s in enumerate(rep_status) if s == "running"]
        done = [i + 1 for i, s in enumerate(rep_status) if s != "pending"]
        repetition = running[0] if running else (done[-1] if done else self._fed_repetition)
        started = t_start[np.isfinite(t_start)]
        t0 = float(started[0]) if len(started) else self._t_first
        elapsed_s = (self._t_last - t0) if self._t_last is not None and t0 is not None else 0.0
        step = STEP_BY_PUMP_STATE.get(self._pump_state, "hold" if running else "waiting")
        self.state.set_step(
            Step(step, repetition, elapsed_s, max(0.0, self.duration_s - elapsed_s))
        )
        if done:
            self._under_way()

    def _under_way(self) -> None:
        """The run is running once any repetition has begun or any sample is in the
        file: a watcher may open it between two repetitions (none running then), and a
        reader may see a repetition's first samples before its status (SWMR refreshes
        each dataset on its own; seen in CI: samples at 0.5 mL, status "starting")."""
        if self.state.status == "starting":
            self.state.status = "running"
