"""One HDF5 file per run, written as the data arrives.

The layout is NeXus-flavoured: an ``NXentry`` per run holding the protocol text, the rig
configuration and the versions it ran with, and per repetition three ``NXlog`` series
(pressure, pump volume, length) on their own time axes with ``units`` attributes.

The whole layout is created before the first sample, then the file is switched to
HDF5's single-writer/multiple-reader (SWMR) mode and only appended to. SWMR orders the
metadata writes so that the file on disk is consistent after every flush: a process
killed with SIGKILL leaves a file that holds everything up to its last flush (at most
``flush_interval_s`` old). Such a file still carries the writer's "open for writing"
flag; ``labrig.recording.run_reader.open_run`` reads it anyway and
``labrig.recording.repair.clear_write_flag`` (``labrig recover``) clears it.
Status strings live in fixed-size datasets, not attributes, because SWMR allows only
writes to existing datasets.

The file is never overwritten: the writer takes the run file's lock
(``labrig.recording.run_file_lock``) before it creates the file, creates it only if it
does not exist, and holds the lock until the file is closed, SWMR or not.
"""

from __future__ import annotations

import contextlib
import datetime as dt
import logging
import os
import platform
import re
import subprocess
import threading
import time
from collections.abc import Callable, Iterator, Mapping
from pathlib import Path

import h5py
import numpy as np

from labrig._version import __version__
from labrig.errors import InputError, LabrigError
from labrig.recording.file_check import vouch_for
from labrig.recording.run_file_lock import RunFileLock
from labrig.recording.run_layout import (
    CAMERA_FIELDS,
    CHUNK,
    EVENT_FIELDS,
    LOG_DESCRIPTION,
    LOG_FIELDS,
    REASON_SIZE,
    REPETITION_STATUSES,
    RUN_STATUSES,
    SPECIMEN_MODEL_DESCRIPTION,
    STATUS_SIZE,
    TIME_SIZE,
    VIDEO_FIELDS,
    repetition_name,
)
from labrig.recording.unwritable import abandon, quiet_h5py_frees

log = logging.getLogger(__name__)


def _now_iso() -> str:
    return dt.datetime.now(dt.UTC).isoformat(timespec="seconds")


def _storable(name: str) -> str:
    """A file name as HDF5 can store it: a byte of the name that is not UTF-8 (Python
    keeps it as a lone surrogate) is written as its escape, ``\\xff``."""
    return name.encode("utf-8", "surrogateescape").decode("utf-8", "backslashreplace")


def _git_commit() -> str:
    """The commit labrig runs from, when it runs from a git checkout."""
    try:
        out = subprocess.run(
            ["git", "rev-parse", "HEAD"],
            cwd=Path(__file__).parent,
            capture_output=True,
            text=True,
            timeout=5,
            check=True,
        )
    except (OSError, subprocess.SubprocessError):
        return "unknown"
    return out.stdout.strip()


def versions() -> dict[str, str]:
    """Versions recorded in every run file."""
    import scipy

    return {
        "labrig": __version__,
        "git_commit": _git_commit(),
        "python": platform.python_version(),
        "numpy": np.__version__,
        "scipy": scipy.__version__,
        "h5py": h5py.__version__,
        "hdf5": h5py.version.hdf5_version,
    }


class RunFileFailed(LabrigError):
    """The run file could not be written (a full disk, the file removed): the run is
    faulted, and never reported complete."""


class RunWriter:
    """Create a run file's layout, then append samples and flush them as they come.

    Thread-safe: the runner's acquisition threads append concurrently. Appended rows
    are gathered in memory and written, then flushed, when the last flush is older than
    ``flush_interval_s`` (host time), so the file on disk is never more than that
    behind. Gathering matters: h5py costs tens of microseconds per dataset operation,
    and a simulated run appends to seven datasets per camera frame and five per pump
    poll many times a second of host time.
    """

    def __init__(
        self,
        path: str | Path,
        *,
        title: str,
        protocol_text: str,
        protocol_path: str,
        rig_config_text: str,
        repetitions: int,
        with_length: bool,
        camera_fps: float = float("nan"),
        with_force: bool = False,
        with_events: bool = False,
        simulated_segments: int = 0,
        specimen_model: str = "segments",
        video_file: str | None = None,
        flush_interval_s: float = 0.5,
        tap: Callable[[int, str, dict[str, np.ndarray]], None] | None = None,
        pump_identity: Mapping[str, str] | None = None,
    ) -> None:
        self.path = Path(path)
        # sees every append (repetition, log, columns) as written: the live view's feed
        self.tap = tap
        try:
            self.path.parent.mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            raise InputError(f"{self.path}: cannot create its folder ({exc.strerror})") from None
        if repetitions < 1:
            raise ValueError("a run has at least one repetition")
        self.repetitions = repetitions
        self.with_length = with_length
        self.camera_fps = camera_fps  # nominal, with a length log (a camera)
        self.with_force = with_force
        self.with_events = with_events
        self.simulated_segments = simulated_segments
        self.specimen_model = specimen_model
        self.video_file = video_file
        # who the pump is, as connect read it (``/entry/pump_identity``); empty: none
        self.pump_identity = dict(pump_identity or {})
        self.flush_interval_s = flush_interval_s
        self._lock = threading.Lock()
        self._closed = False
        self._failure = ""  # why the file could not be written, once it could not
        self._unwritable = False  # HDF5 failed to write it: never to be closed
        # rows appended since the last write, per group path, in arrival order
        self._pending: dict[str, list[dict[str, np.ndarray]]] = {}
        self._datasets: dict[tuple[str, str], h5py.Dataset] = {}
        self._claim = RunFileLock(self.path, "run").acquire("choose another --out")
        created: h5py.File | None = None
        try:
            self._file = created = self._create_file()
            self._claim.hold_new_file(created.id.get_vfd_handle(), "choose another --out")
            self._identity = self._claim.file_identity()
            self._create_layout(title, protocol_text, protocol_path, rig_config_text)
            self._file.swmr_mode = True
        except BaseException:
            if created is not None:
                made = os.fstat(created.id.get_vfd_handle())
                created.close()
                if _identity_at(self.path) == (made.st_dev, made.st_ino):
                    self.path.unlink()  # this writer's own new file, half laid out
            self._claim.release()
            raise
        self._last_flush = time.monotonic()

    def _create_file(self) -> h5py.File:
        """The new run file, made by HDF5 only if nothing is at the path (its exclusive
        create, ``O_EXCL``): an existing file, a finished run or another program's, is
        never truncated, whatever moves onto the path at any moment."""
        try:
            return h5py.File(self.path, "x", libver="latest")
        except FileExistsError:
            raise InputError(
                f"{self.path}: a file is already there; a run never writes over one "
                "(labrig run --overwrite moves it aside first)"
            ) from None
        except OSError as exc:
            raise InputError(f"{self.path}: cannot create the run file ({exc})") from None

    # --- layout --------------------------------------------------------------------
    def _create_layout(
        self, title: str, protocol_text: str, protocol_path: str, rig_config_text: str
    ) -> None:
        f = self._file
        f.attrs.update(
            NX_class="NXroot",
            default="entry",
            creator=f"labrig {__version__}",
            file_time=_now_iso(),
        )
        entry = f.create_group("entry")
        entry.attrs.update(NX_class="NXentry", default="data")
        entry["title"] = title
        entry["start_time"] = np.array(_now_iso().encode(), dtype=f"S{TIME_SIZE}")
        entry["end_time"] = np.array(b"", dtype=f"S{TIME_SIZE}")
        entry["status"] = np.array(b"running", dtype=f"S{STATUS_SIZE}")
        entry["reason"] = np.array(b"", dtype=f"S{REASON_SIZE}")
        # False until the run's last stop is confirmed: a killed run confirmed none
        entry["pump_stop_confirmed"] = False
        protocol = entry.create_dataset("protocol", data=protocol_text)
        protocol.attrs["source_file"] = _storable(protocol_path)
        entry["rig_config"] = rig_config_text
        # the protocol's specimen.model, for any HDF5 tool: "none" when the run had no
        # model (its segments are labels, nothing was predicted)
        model = entry.create_dataset("specimen_model", data=self.specimen_model)
        model.attrs["description"] = SPECIMEN_MODEL_DESCRIPTION
        version_group = entry.create_group("versions")
        version_group.attrs["NX_class"] = "NXcollection"
        for name, value in versions().items():
            version_group[name] = value
        if self.pump_identity:
            pump = entry.create_group("pump_identity")
            pump.attrs.update(
                NX_class="NXcollection",
                description="the pump as its connection found it ('version' reply, and "
                "what it was doing then)",
            )
            for name, text in self.pump_identity.items():
                pump[name] = text
        zero = entry.create_group("zero")
        zero.attrs["NX_class"] = "NXcollection"
        zero.create_dataset("offset_kpa", data=np.nan).attrs["units"] = "kPa"

        reps = entry.create_group("repetitions")
        reps.attrs["NX_class"] = "NXcollection"
        n = self.repetitions
        reps["status"] = np.array([b"pending"] * n, dtype=f"S{STATUS_SIZE}")
        reps["reason"] = np.array([b""] * n, dtype=f"S{REASON_SIZE}")
        reps.create_dataset("t_start", data=np.full(n, np.nan)).attrs["units"] = "s"
        reps.create_dataset("t_end", data=np.full(n, np.nan)).attrs["units"] = "s"
        for index in range(1, n + 1):
            rep = reps.create_group(repetition_name(index))
            rep.attrs["NX_class"] = "NXcollection"
            for log in LOG_FIELDS:
                if (log == "length" and not self.with_length) or (
                    log == "force" and not self.with_force
                ):
                    continue
                self._create_log(rep, log)
        if self.with_length:
            camera = entry.create_group("camera")
            camera.attrs["NX_class"] = "NXcollection"
            for field, holds in CAMERA_FIELDS.items():
                value = self.camera_fps if field == "nominal_fps" else np.nan
                camera.create_dataset(field, data=value).attrs.update(units="Hz", description=holds)
        if self.with_events:
            events = self._create_log(entry, "events", EVENT_FIELDS)
            events.attrs["description"] = "technician prompts and reservoir steps, in order"
        if self.simulated_segments:
            fields = {"time": ("f8", "s")}
            fields |= {f"v{i + 1}": ("f8", "mL") for i in range(self.simulated_segments)}
            simulation = entry.create_group("simulation")
            simulation.attrs["NX_class"] = "NXcollection"
            volumes = self._create_log(simulation, "segment_volumes", fields)
            volumes.attrs["description"] = (
                "the simulated specimen's volume in each segment (the simulation's truth; "
                "a real rig cannot measure it)"
            )
        if self.video_file is not None:
            video = self._create_log(entry, "video", VIDEO_FIELDS)
            video.attrs.update(
                description="time of each frame of the run's video, in the video's order",
                file=_storable(self.video_file),
            )

    @staticmethod
    def _create_log(parent: h5py.Group, log: str, fields=None) -> h5py.Group:
        group = parent.create_group(log)
        if fields is None:
            fields = LOG_FIELDS[log]
            group.attrs.update(NX_class="NXlog", description=LOG_DESCRIPTION[log])
        else:
            group.attrs["NX_class"] = "NXlog"
        for field, (dtype, units) in fields.items():
            dataset = group.create_dataset(
                field, shape=(0,), maxshape=(None,), chunks=(CHUNK,), dtype=dtype
            )
            if units:
                dataset.attrs["units"] = units
        return group

    # --- appending -----------------------------------------------------------------
    def _append(self, repetition: int, log: str, columns: dict[str, np.ndarray]) -> None:
        if not 1 <= repetition <= self.repetitions:
            raise ValueError(f"repetition {repetition} outside 1..{self.repetitions}")
        rows = self._append_to(f"entry/repetitions/{repetition_name(repetition)}/{log}", columns)
        if rows is not None and self.tap is not None:
            self.tap(repetition, log, rows)

    def _append_to(self, where: str, columns: dict[str, np.ndarray]) -> dict | None:
        """Gather rows for the group at ``where``; the rows, or None if there were none."""
        rows = {field: np.atleast_1d(values) for field, values in columns.items()}
        lengths = {len(values) for values in rows.values()}
        if len(lengths) != 1:
            raise ValueError(f"{where}: columns of different lengths {sorted(lengths)}")
        (count,) = lengths
        if count == 0:
            return None
        with self._lock:
            if self._closed:
                raise RuntimeError(f"{self.path}: the run file is already closed")
            self._pending.setdefault(where, []).append(rows)
            with self._io():
                self._flush_if_due()
        return rows

    def _write_pending(self) -> None:
        """Write the gathered rows, one resize and one write per dataset (under the lock)."""
        for where, chunks in self._pending.items():
            for field in chunks[0]:
                values = np.concatenate([chunk[field] for chunk in chunks])
                dataset = self._dataset(where, field)
                start = dataset.shape[0]
                dataset.resize((start + len(values),))
                dataset[start:] = values
        self._pending.clear()

    def _dataset(self, where: str, field: str) -> h5py.Dataset:
        """The dataset ``field`` of the group at ``where``, looked up once: an h5py path
        lookup costs more than the write of a flush's rows."""
        key = (where, field)
        dataset = self._datasets.get(key)
        if dataset is None:
            dataset = self._datasets[key] = self._file[where][field]
        return dataset

    def append_pressure(self, repetition: int, t_s, pressure_kpa, out_of_range) -> None:
        self._append(
            repetition,
            "pressure",
            {"time": t_s, "value": pressure_kpa, "out_of_range": out_of_range},
        )

    def append_pump(self, repetition: int, t_s, volume_ml, infused_ml, withdrawn_ml, state) -> None:
        states = np.array([str(s).encode()[:STATUS_SIZE] for s in np.atleast_1d(state)])
        self._append(
            repetition,
            "pump",
            {
                "time": t_s,
                "value": volume_ml,
                "infused": infused_ml,
                "withdrawn": withdrawn_ml,
                "state": states.astype(f"S{STATUS_SIZE}"),
            },
        )

    def append_length(self, repetition: int, t_s, length_mm, x1, y1, x2, y2, ok) -> None:
        if not self.with_length:
            raise ValueError("this run was created without a length (camera) log")
        self._append(
            repetition,
            "length",
            {"time": t_s, "value": length_mm, "x1": x1, "y1": y1, "x2": x2, "y2": y2, "ok": ok},
        )

    def append_force(self, repetition: int, t_s, force_n) -> None:
        if not self.with_force:
            raise ValueError("this run was created without a force (load cell) log")
        self._append(repetition, "force", {"time": t_s, "value": force_n})

    def append_event(self, t_s: float, kind: str, volume_ml: float, message: str = "") -> None:
        """A technician prompt or a reservoir step (entry/events)."""
        if not self.with_events:
            raise ValueError("this run was created without an events log")
        self._append_to(
            "entry/events",
            {
                "time": np.array([t_s]),
                "kind": np.array([kind.encode()[:STATUS_SIZE]], dtype=f"S{STATUS_SIZE}"),
                "volume": np.array([volume_ml]),
                "message": np.array([message.encode()[:REASON_SIZE]], dtype=f"S{REASON_SIZE}"),
            },
        )

    def append_segment_volumes(self, t_s, volumes_ml: np.ndarray) -> None:
        """The simulated plant's segment volumes (rows: times)."""
        columns = {"time": t_s}
        columns |= {f"v{i + 1}": volumes_ml[:, i] for i in range(self.simulated_segments)}
        self._append_to("entry/simulation/segment_volumes", columns)

    def append_video_frame(self, repetition: int, t_s) -> None:
        """The time of the next frame(s) written to the run's video."""
        if self.video_file is None:
            raise ValueError("this run was created without a video")
        t = np.atleast_1d(t_s)
        self._append_to("entry/video", {"time": t, "repetition": np.full(len(t), repetition)})

    # --- status ----------------------------------------------------------------------
    def set_zero_offset(self, offset_kpa: float) -> None:
        with self._lock, self._io():
            self._file["entry/zero/offset_kpa"][()] = offset_kpa
            self._flush_if_due(force=True)

    def set_measured_fps(self, fps: float | None) -> None:
        """The camera's real frame rate over the run (None: fewer than two frames)."""
        if not self.with_length:
            raise ValueError("this run was created without a camera")
        with self._lock, self._io():
            self._file["entry/camera/measured_fps"][()] = np.nan if fps is None else fps
            self._flush_if_due(force=True)

    def set_repetition_status(
        self,
        repetition: int,
        status: str,
        reason: str = "",
        *,
        t_start_s: float | None = None,
        t_end_s: float | None = None,
    ) -> None:
        if status not in REPETITION_STATUSES:
            raise ValueError(f"unknown repetition status {status!r}")
        with self._lock, self._io():
            reps = self._file["entry/repetitions"]
            i = repetition - 1
            reps["status"][i] = status.encode()
            reps["reason"][i] = reason.encode()[:REASON_SIZE]
            if t_start_s is not None:
                reps["t_start"][i] = t_start_s
            if t_end_s is not None:
                reps["t_end"][i] = t_end_s
            self._flush_if_due(force=True)

    def flush(self) -> None:
        with self._lock, self._io():
            self._flush_if_due(force=True)

    def _flush_if_due(self, force: bool = False) -> None:
        now = time.monotonic()
        if force or now - self._last_flush >= self.flush_interval_s:
            self._check_still_there()
            self._write_pending()
            self._file.flush()
            self._last_flush = now

    def finalise(self, status: str, reason: str = "", *, pump_stop_confirmed: bool = True) -> None:
        """Record how the run ended and close the file cleanly (idempotent).
        ``pump_stop_confirmed``: False when the pump never confirmed the run's last
        stop (it may still be moving). RunFileFailed (after letting go of the file) if
        it could not be written or is gone: a file HDF5 failed to write is left as of
        its last good flush, flagged open like a killed run's (``labrig recover``)."""
        if status not in RUN_STATUSES[1:]:
            raise ValueError(f"a run ends complete, aborted or faulted, not {status!r}")
        with self._lock:
            if self._closed:
                return
            try:
                with self._io():
                    if not self._unwritable:  # a file that failed once fails again
                        self._write_end(status, reason, pump_stop_confirmed)
                        self._file.close()
            except RunFileFailed:
                pass  # remembered in _failure
            finally:
                if self._unwritable:
                    self._abandon()
                self._closed = True
                self._claim.release()
            with contextlib.suppress(RunFileFailed):  # remembered in _failure
                self._check_still_there()
        if self._failure:
            raise RunFileFailed(self._failure)
        vouch_for(self.path)  # written here: no reader needs to walk it first

    @property
    def closed(self) -> bool:
        return self._closed

    def _write_end(self, status: str, reason: str, pump_stop_confirmed: bool) -> None:
        self._write_pending()
        entry = self._file["entry"]
        entry["status"][()] = status.encode()
        entry["reason"][()] = reason.encode()[:REASON_SIZE]
        entry["pump_stop_confirmed"][()] = pump_stop_confirmed
        entry["end_time"][()] = _now_iso().encode()
        reps = entry["repetitions"]
        states = reps["status"][:]
        for i, state in enumerate(states):
            # a repetition still running when the run stopped shares the run's fate
            if state == b"running":
                reps["status"][i] = b"complete" if status == "complete" else status.encode()
                reps["reason"][i] = reason.encode()[:REASON_SIZE]
        self._file.flush()

    # --- a file that cannot be written --------------------------------------------------
    @contextlib.contextmanager
    def _io(self) -> Iterator[None]:
        """HDF5's failure to write (a full disk, a file size limit, a device gone) as
        one line, remembered: the run is faulted by it and the end reports it."""
        try:
            yield
        except (OSError, RuntimeError) as exc:
            if isinstance(exc, RunFileFailed):
                raise
            quiet_h5py_frees()
            found = re.search(r"errno = (\d+)", str(exc))
            errno = getattr(exc, "errno", None) or (int(found.group(1)) if found else None)
            why = os.strerror(errno) if errno else "HDF5 could not write it"
            message = f"{self.path}: cannot write the run file ({why}); it holds what was "
            message += "written before"
            self._failure = self._failure or message
            self._unwritable = True
            raise RunFileFailed(message) from None

    def _check_still_there(self) -> None:
        """RunFileFailed once the path no longer names the file written (removed, its
        folder deleted): writing on would go on into a file nobody can open."""
        if _identity_at(self.path) != self._identity:
            message = (
                f"{self.path}: the run file is gone (removed, or its folder deleted, while the "
                "run wrote it); what it held is lost"
            )
            self._failure = self._failure or message
            raise RunFileFailed(message)

    def _abandon(self) -> None:
        """Let go of a file HDF5 cannot write, without closing it
        (``labrig.recording.unwritable``); on disk it is as of its last good flush,
        consistent (SWMR)."""
        abandon(self._file.id, *(d.id for d in self._datasets.values()))
        self._datasets.clear()


def _stat_or_none(path: Path) -> os.stat_result | None:
    try:
        return os.stat(path)
    except OSError:
        return None


def _identity_at(path: Path) -> tuple[int, int] | None:
    """(device, inode) of the file ``path`` names now; None if it names none."""
    there = _stat_or_none(path)
    return None if there is None else (there.st_dev, there.st_ino)
