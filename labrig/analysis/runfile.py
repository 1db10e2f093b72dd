"""A run file read back for review and analysis, every piece checked and every absence
named.

``labrig.recording`` writes the layout and knows how to open a file a killed writer left;
this module reads what the analysis needs into plain arrays and turns whatever is wrong
with a file into one ``InputError`` line: a file that is not HDF5, one cut short (a copy
that stopped early), a foreign HDF5 file, a repetition or a field that is missing, a
dataset that cannot be read. It also reports whether the writer's "open for writing"
flag is still set, so commands can say that ``labrig recover`` applies.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import h5py
import numpy as np

from labrig.config.protocol import Protocol, parse_protocol
from labrig.errors import InputError
from labrig.recording.file_check import superblock_facts, truncation, unopenable
from labrig.recording.run_layout import repetition_name
from labrig.recording.run_reader import LogSeries, decode, open_run, read_values

# fields the analysis cannot do without, per log; other fields are read when present
REQUIRED_FIELDS = {
    "pressure": ("time", "value"),
    "pump": ("time", "value"),
    "length": ("time", "value"),
}


@dataclass(frozen=True)
class Repetition:
    """One repetition's raw series as recorded (length is None without a camera)."""

    index: int
    status: str
    reason: str
    t_start_s: float
    t_end_s: float
    pressure: LogSeries
    pump: LogSeries
    length: LogSeries | None

    @property
    def name(self) -> str:
        return repetition_name(self.index)


@dataclass(frozen=True)
class RunRecord:
    """What a run file holds, as plain values."""

    path: Path
    title: str
    status: str
    reason: str
    start_time: str
    end_time: str
    protocol_text: str
    protocol: Protocol
    rig_config_text: str
    versions: dict[str, str]
    zero_offset_kpa: float
    repetitions: tuple[Repetition, ...]
    writer_flag_set: bool


def _diagnose_unopenable(path: Path, error: InputError) -> InputError:
    """A clearer message than HDF5's for the files it refuses to open."""
    return InputError(unopenable(path, str(error)))


def _read(group: h5py.Group, name: str, where: str):
    """One dataset's value, or InputError naming it when it is absent or unreadable."""
    if name not in group:
        raise InputError(f"{where}: missing {group.name.rstrip('/')}/{name}")
    try:
        return read_values(group[name], where)
    except (OSError, KeyError, ValueError) as exc:
        raise InputError(f"{where}: cannot read {group.name}/{name} ({exc})") from None


def _read_log(rep: h5py.Group, log: str, where: str, growing: bool) -> LogSeries:
    """One NXlog; ``growing``: its writer may be appending (the file is flagged open), so
    its fields, grown one after another, are cut to the rows all of them hold."""
    group = rep[log]
    for field in REQUIRED_FIELDS[log]:
        if field not in group:
            raise InputError(f"{where}: missing {group.name}/{field}")
    fields = {name: np.asarray(_read(group, name, where)) for name in group if name != "time"}
    time_s = np.asarray(_read(group, "time", where), dtype=float)
    if growing:
        rows = min(len(values) for values in (time_s, *fields.values()))
        time_s = time_s[:rows]
        fields = {name: values[:rows] for name, values in fields.items()}
    for name, values in fields.items():
        if len(values) != len(time_s):
            raise InputError(
                f"{where}: {group.name}/{name} has {len(values)} values for {len(time_s)} times"
            )
    return LogSeries(time_s, fields)


def _read_repetitions(entry: h5py.Group, where: str, growing: bool) -> tuple[Repetition, ...]:
    if "repetitions" not in entry:
        raise InputError(f"{where}: missing /entry/repetitions")
    reps = entry["repetitions"]
    statuses = _read(reps, "status", where)
    reasons = _read(reps, "reason", where)
    n = len(statuses)
    t_start = _read(reps, "t_start", where) if "t_start" in reps else np.full(n, np.nan)
    t_end = _read(reps, "t_end", where) if "t_end" in reps else np.full(n, np.nan)
    out = []
    for index in range(1, n + 1):
        name = repetition_name(index)
        if name not in reps:
            raise InputError(
                f"{where}: missing /entry/repetitions/{name} (the run lists {n} repetitions)"
            )
        rep = reps[name]
        for log in ("pressure", "pump"):
            if log not in rep:
                raise InputError(f"{where}: missing /entry/repetitions/{name}/{log}")
        out.append(
            Repetition(
                index=index,
                status=decode(statuses[index - 1]),
                reason=decode(reasons[index - 1]),
                t_start_s=float(t_start[index - 1]),
                t_end_s=float(t_end[index - 1]),
                pressure=_read_log(rep, "pressure", where, growing),
                pump=_read_log(rep, "pump", where, growing),
                length=_read_log(rep, "length", where, growing) if "length" in rep else None,
            )
        )
    return tuple(out)


def _text(entry: h5py.Group, name: str, where: str) -> str:
    return decode(_read(entry, name, where)) if name in entry else ""


def open_checked(path: Path, opener: Callable[[Path], h5py.File] = open_run) -> h5py.File:
    """The run file opened by ``opener``, checked to be a labrig run file; InputError
    (one line) saying why not: not HDF5, truncated, no ``/entry``."""
    if path.is_file() and (why := truncation(path)):
        # SWMR read mode would open it, and fail somewhere in the middle of the data
        raise InputError(why)
    try:
        run = opener(path)
    except InputError as exc:
        if path.is_file():
            raise _diagnose_unopenable(path, exc) from None
        raise
    if "entry" not in run:
        found = ", ".join(sorted(run)) or "nothing"
        run.close()
        raise InputError(f"{path}: not a labrig run file: missing /entry (the file holds {found})")
    return run


def writer_flag_set(path: Path) -> bool:
    """Whether the file still carries its writer's "open for writing" flag (a run being
    recorded, or one whose writer was killed)."""
    facts = superblock_facts(path) if path.is_file() else None
    return facts is not None and facts[1] != 0


def load_run(path: str | Path, opener: Callable[[Path], h5py.File] = open_run) -> RunRecord:
    """Read a run file for analysis; InputError (one line) for anything missing.
    ``opener`` opens the file (the Python API's opens it without HDF5's file lock)."""
    path = Path(path)
    where = str(path)
    flagged = writer_flag_set(path)
    with open_checked(path, opener) as run:
        entry = run["entry"]
        protocol_text = _text(entry, "protocol", where)
        if not protocol_text:
            raise InputError(f"{where}: missing /entry/protocol")
        protocol = parse_protocol(protocol_text, f"{where}:/entry/protocol")
        versions = {}
        if "versions" in entry:
            versions = {name: _text(entry["versions"], name, where) for name in entry["versions"]}
        zero = np.nan
        if "zero" in entry and "offset_kpa" in entry["zero"]:
            zero = float(_read(entry["zero"], "offset_kpa", where))
        return RunRecord(
            path=path,
            title=_text(entry, "title", where),
            status=_text(entry, "status", where) or "unknown",
            reason=_text(entry, "reason", where),
            start_time=_text(entry, "start_time", where),
            end_time=_text(entry, "end_time", where),
            protocol_text=protocol_text,
            protocol=protocol,
            rig_config_text=_text(entry, "rig_config", where),
            versions=versions,
            zero_offset_kpa=zero,
            repetitions=_read_repetitions(entry, where, flagged),
            writer_flag_set=flagged,
        )
