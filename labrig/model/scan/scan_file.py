"""The HDF5 file of a scan: its layout, appending chunk results, resuming, reading.

Layout (created before the first chunk; every chunk appended and flushed as it comes)::

    /                      attrs: kind, labrig version, n, deflate, chunk_size,
                           n_combinations, library label and digest, complete,
                           elapsed_s, workers, parent/worker peak memory (MiB)
    /segments/name         (S,) the library's segment names; a row's segment indices
                           point here
    /segments/tables/<i>   v_ml, p_kpa, l_mm of segment i as scanned
    /chunks/done           (C,) bool: chunk i is complete in the file
    /chunks/row_start|row_stop, failure_start|failure_stop  (C,) its rows
    /chunks/seconds        (C,) compute time of the chunk
    /transitions/actuator  (M,) rank of the combination (itertools.combinations order)
    /transitions/segments  (M, n) segment indices
    /transitions/direction, v_ml, alpha, beta, stable, dE, dv, dl, dp   (M,)
    /failures/actuator, segments, error   actuators whose path failed, with the reason

Chunks are written in order by the parent process only, so ``done`` is always a prefix
and rows are sorted by actuator. A chunk's rows are written before it is marked done; a
scan killed in between leaves rows past the last done chunk, which ``resume`` drops.
"""

from __future__ import annotations

import math
import time
from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass
from functools import cached_property
from pathlib import Path

import numpy as np

from labrig._version import __version__
from labrig.errors import InputError
from labrig.model.scan.scan import (
    TRANSITION_FIELDS,
    Chunk,
    ChunkResult,
    ScanLibrary,
    make_chunks,
)

KIND = "labrig model scan"
_UNITS = {"v_ml": "mL", "dE": "1", "dv": "1", "dl": "1", "dp": "1"}
_DTYPES = {
    "direction": np.int8,
    "alpha": np.int8,
    "beta": np.int8,
    "stable": np.bool_,
}
_ROWS_PER_HDF5_CHUNK = 65536


def _growing(group, name: str, dtype, width: int | None = None):
    shape = (0,) if width is None else (0, width)
    maxshape = (None,) if width is None else (None, width)
    chunks = (_ROWS_PER_HDF5_CHUNK,) if width is None else (_ROWS_PER_HDF5_CHUNK // width, width)
    return group.create_dataset(name, shape, maxshape=maxshape, dtype=dtype, chunks=chunks)


def _append(dataset, values) -> None:
    if not len(values):  # most chunks fail nowhere: two h5py calls saved per dataset
        return
    start = dataset.shape[0]
    dataset.resize(start + len(values), axis=0)
    dataset[start:] = values


class ScanFile:
    """A scan's HDF5 file open for writing (``create`` or ``resume``)."""

    def __init__(self, h5, path: Path) -> None:
        self.h5 = h5
        self.path = path
        self.n = int(h5.attrs["n"])
        self.chunk_size = int(h5.attrs["chunk_size"])
        self.deflate = bool(h5.attrs["deflate"])
        self.n_segments = len(h5["segments/name"])
        self._started = time.perf_counter()
        self._elapsed_before = float(h5.attrs["elapsed_s"])

    # --- opening ------------------------------------------------------------------------
    @classmethod
    def create(
        cls, path: Path, library: ScanLibrary, n: int, *, chunk_size: int, deflate: bool
    ) -> ScanFile:
        import h5py

        total = math.comb(len(library.curves), n)
        n_chunks = len(make_chunks(len(library.curves), n, chunk_size))
        try:
            # "x": a file that appeared since the command checked (the compile can take
            # minutes) is refused, never truncated
            h5 = h5py.File(path, "x")
        except FileExistsError:
            raise InputError(
                f"--out {path}: the file exists; --resume continues it, or remove it first"
            ) from None
        attrs = h5.attrs
        attrs["kind"] = KIND
        attrs["labrig_version"] = __version__
        attrs["n"] = n
        attrs["deflate"] = deflate
        attrs["chunk_size"] = chunk_size
        attrs["n_combinations"] = total
        attrs["library"] = library.label
        attrs["library_digest"] = library.digest
        attrs["created"] = time.strftime("%Y-%m-%dT%H:%M:%S%z")
        attrs["complete"] = False
        attrs["elapsed_s"] = 0.0
        attrs["workers"] = 0
        attrs["parent_peak_rss_mib"] = 0.0
        attrs["worker_peak_rss_mib"] = 0.0
        segments = h5.create_group("segments")
        segments.create_dataset(
            "name", data=np.array(library.names, dtype=object), dtype=h5py.string_dtype()
        )
        tables = segments.create_group("tables")
        for i, curve in enumerate(library.curves):
            table = tables.create_group(str(i))
            table.attrs["name"] = curve.name
            table.attrs["source"] = curve.source
            for key, values, unit in (
                ("v_ml", curve.v_ml, "mL"),
                ("p_kpa", curve.p_kpa, "kPa"),
                ("l_mm", curve.l_mm, "mm"),
            ):
                table.create_dataset(key, data=np.asarray(values)).attrs["units"] = unit
        chunks = h5.create_group("chunks")
        chunks.create_dataset("done", data=np.zeros(n_chunks, dtype=bool))
        for key in ("row_start", "row_stop", "failure_start", "failure_stop"):
            chunks.create_dataset(key, data=np.zeros(n_chunks, dtype=np.int64))
        chunks.create_dataset("seconds", data=np.zeros(n_chunks))
        rows = h5.create_group("transitions")
        _growing(rows, "actuator", np.int64)
        _growing(rows, "segments", np.int16, n)
        for name in TRANSITION_FIELDS:
            dataset = _growing(rows, name, _DTYPES.get(name, np.float64))
            if name in _UNITS:
                dataset.attrs["units"] = _UNITS[name]
        rows["direction"].attrs["meaning"] = "+1 inflate, -1 deflate"
        failures = h5.create_group("failures")
        _growing(failures, "actuator", np.int64)
        _growing(failures, "segments", np.int16, n)
        _growing(failures, "error", h5py.string_dtype())
        h5.flush()
        return cls(h5, path)

    @classmethod
    def resume(cls, path: Path, library: ScanLibrary, n: int, *, deflate: bool) -> ScanFile:
        """Open an interrupted scan to continue it; InputError unless it is a scan of the
        same library, n and direction(s)."""
        import h5py

        try:
            h5 = h5py.File(path, "r+")
        except OSError as exc:
            raise InputError(f"{path}: cannot open it to resume ({exc})") from None
        try:
            attrs = h5.attrs
            if attrs.get("kind") != KIND:
                raise InputError(f"{path}: not a labrig scan file; cannot resume it")
            wanted = {"n": n, "deflate": deflate, "library_digest": library.digest}
            for key, value in wanted.items():
                stored = attrs[key].item() if hasattr(attrs[key], "item") else attrs[key]
                if stored != value:
                    what = (
                        "other segments' tables"
                        if key == "library_digest"
                        else f"{key} = {stored}, not {value}"
                    )
                    raise InputError(
                        f"{path}: scanned with {what}; resume with the same --n, --library "
                        "and --deflate, or start a new file"
                    )
            done = h5["chunks/done"][:]
            kept = int(np.argmin(done)) if not done.all() else len(done)
            if done[kept:].any():
                raise InputError(f"{path}: chunks were not written in order; cannot resume")
            # rows of a chunk that was being written when the scan stopped
            row_stop = int(h5["chunks/row_stop"][kept - 1]) if kept else 0
            failure_stop = int(h5["chunks/failure_stop"][kept - 1]) if kept else 0
            for name in ("actuator", "segments", *TRANSITION_FIELDS):
                h5["transitions"][name].resize(row_stop, axis=0)
            for name in ("actuator", "segments", "error"):
                h5["failures"][name].resize(failure_stop, axis=0)
        except BaseException:
            h5.close()
            raise
        return cls(h5, path)

    # --- writing ------------------------------------------------------------------------
    def pending_chunks(self) -> list[Chunk]:
        done = self.h5["chunks/done"][:]
        chunks = make_chunks(self.n_segments, self.n, self.chunk_size, deflate=self.deflate)
        return [c for c in chunks if not done[c.index]]

    @property
    def chunks_done(self) -> int:
        return int(self.h5["chunks/done"][:].sum())

    @property
    def n_chunks(self) -> int:
        return len(self.h5["chunks/done"])

    def append(self, results: Sequence[ChunkResult]) -> None:
        """Write the rows of chunks that follow one another (the next ones in order),
        then mark them done, then flush: one write per dataset for them all, since a
        scan's parent spent more time in h5py's work per call than in writing (n = 3:
        199 chunks of 36 actuators, 30 calls each)."""
        if not results:
            return
        first, last = results[0].index, results[-1].index + 1
        if [r.index for r in results] != list(range(first, last)):
            raise ValueError(f"chunks {[r.index for r in results]}: not one after another")
        h5 = self.h5
        rows, failures, chunks = h5["transitions"], h5["failures"], h5["chunks"]
        index = {}
        for key, group, field in (
            ("row", rows, "actuator"),
            ("failure", failures, "failed_actuator"),
        ):
            counts = np.array([len(getattr(r, field)) for r in results], dtype=np.int64)
            stops = group["actuator"].shape[0] + np.cumsum(counts)
            index[f"{key}_start"], index[f"{key}_stop"] = stops - counts, stops

        def joined(field: str) -> np.ndarray:
            return np.concatenate([getattr(r, field) for r in results])

        _append(rows["actuator"], joined("actuator"))
        _append(rows["segments"], joined("segments"))
        for name in TRANSITION_FIELDS:
            _append(rows[name], np.concatenate([r.columns[name] for r in results]))
        _append(failures["actuator"], joined("failed_actuator"))
        _append(failures["segments"], joined("failed_segments"))
        errors = [e for r in results for e in r.failed_error]
        _append(failures["error"], np.array(errors, dtype=object))
        for key, values in index.items():
            chunks[key][first:last] = values
        chunks["seconds"][first:last] = [r.seconds for r in results]
        chunks["done"][first:last] = True
        attrs = h5.attrs
        peak = max(r.peak_rss_mib for r in results)
        attrs["worker_peak_rss_mib"] = max(float(attrs["worker_peak_rss_mib"]), peak)
        attrs["elapsed_s"] = self._elapsed_before + time.perf_counter() - self._started
        h5.flush()

    def close(self, *, workers: int, parent_peak_rss_mib: float) -> None:
        attrs = self.h5.attrs
        attrs["complete"] = bool(self.h5["chunks/done"][:].all())
        attrs["elapsed_s"] = self._elapsed_before + time.perf_counter() - self._started
        attrs["workers"] = workers
        attrs["parent_peak_rss_mib"] = max(float(attrs["parent_peak_rss_mib"]), parent_peak_rss_mib)
        self.h5.close()


# --- reading ---------------------------------------------------------------------------
# rows read at a time by ``ScanData.row_blocks`` (a block of all fields is ~60 MB)
BLOCK_ROWS = 1 << 20


@dataclass(frozen=True)
class ScanData:
    """A scan file: its metadata and failures in memory, its rows (sorted by actuator,
    as written) read from the file when first asked for (``actuator``, ``segments``,
    one column of ``columns`` at a time) or block by block (``row_blocks``), so that a
    summary of the 5 million rows of n = 5 does not hold them all at once."""

    path: Path
    names: list[str]
    n: int
    n_combinations: int
    actuators_done: int
    complete: bool
    deflate: bool
    elapsed_s: float
    workers: int
    parent_peak_rss_mib: float
    worker_peak_rss_mib: float
    row_stop: int
    failed_actuator: np.ndarray
    failed_segments: np.ndarray
    failed_error: list[str]

    def segment_names(self, row_segments) -> list[str]:
        return [self.names[i] for i in row_segments]

    def names_at_row(self, row: int) -> list[str]:
        """The segment names of one row, read alone (not the whole column)."""
        return self.segment_names(self._read("segments", row, row + 1)[0])

    def _read(self, name: str, start: int = 0, stop: int | None = None) -> np.ndarray:
        import h5py

        stop = self.row_stop if stop is None else min(stop, self.row_stop)
        with h5py.File(self.path, "r") as h5:
            return h5["transitions"][name][start:stop]

    @cached_property
    def actuator(self) -> np.ndarray:
        return self._read("actuator")

    @cached_property
    def segments(self) -> np.ndarray:
        return self._read("segments")

    @cached_property
    def columns(self) -> Mapping[str, np.ndarray]:
        """TRANSITION_FIELDS -> the whole column, each read on first use."""
        return _LazyColumns(self)

    def row_blocks(self, size: int = BLOCK_ROWS) -> Iterator[tuple[np.ndarray, dict]]:
        """(actuator, {field: column}) for consecutive blocks of at most ``size`` rows."""
        import h5py

        with h5py.File(self.path, "r") as h5:
            rows = h5["transitions"]
            for start in range(0, self.row_stop, size):
                stop = min(start + size, self.row_stop)
                yield (
                    rows["actuator"][start:stop],
                    {name: rows[name][start:stop] for name in TRANSITION_FIELDS},
                )


class _LazyColumns(Mapping):
    def __init__(self, data: ScanData) -> None:
        self._data = data
        self._loaded: dict[str, np.ndarray] = {}

    def __getitem__(self, name: str) -> np.ndarray:
        if name not in TRANSITION_FIELDS:
            raise KeyError(name)
        if name not in self._loaded:
            self._loaded[name] = self._data._read(name)
        return self._loaded[name]

    def __iter__(self) -> Iterator[str]:
        return iter(TRANSITION_FIELDS)

    def __len__(self) -> int:
        return len(TRANSITION_FIELDS)


def read_scan(path: Path) -> ScanData:
    """Open a scan file (complete or not); InputError for anything else. The rows stay
    in the file until asked for (``ScanData``)."""
    import h5py

    path = Path(path)
    if not path.is_file():
        raise InputError(f"{path}: no such file")
    try:
        h5 = h5py.File(path, "r")
    except OSError:
        raise InputError(f"{path}: not an HDF5 file") from None
    with h5:
        attrs = h5.attrs
        if attrs.get("kind") != KIND:
            raise InputError(f"{path}: not a labrig scan file (made by `labrig model scan`)")
        done = h5["chunks/done"][:]
        chunk_size = int(attrs["chunk_size"])
        total = int(attrs["n_combinations"])
        kept = int(np.argmin(done)) if not done.all() else len(done)
        row_stop = int(h5["chunks/row_stop"][kept - 1]) if kept else 0
        failure_stop = int(h5["chunks/failure_stop"][kept - 1]) if kept else 0
        failures = h5["failures"]
        return ScanData(
            path=path,
            names=[s.decode() if isinstance(s, bytes) else s for s in h5["segments/name"][:]],
            n=int(attrs["n"]),
            n_combinations=total,
            actuators_done=min(kept * chunk_size, total),
            complete=bool(attrs["complete"]),
            deflate=bool(attrs["deflate"]),
            elapsed_s=float(attrs["elapsed_s"]),
            workers=int(attrs["workers"]),
            parent_peak_rss_mib=float(attrs["parent_peak_rss_mib"]),
            worker_peak_rss_mib=float(attrs["worker_peak_rss_mib"]),
            row_stop=row_stop,
            failed_actuator=failures["actuator"][:failure_stop],
            failed_segments=failures["segments"][:failure_stop],
            failed_error=[
                e.decode() if isinstance(e, bytes) else e for e in failures["error"][:failure_stop]
            ],
        )
