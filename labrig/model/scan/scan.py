"""Scans: every actuator that can be built from n segments of a library, and its
transitions.

The unit of work is a ``Chunk``: a run of consecutive combinations in lexicographic
order, named by its index and its first and last rank. ``run_chunk(library, chunk)`` is a
pure function, chunk in, ``ChunkResult`` (plain numpy arrays) out: it never touches the
file, so the same chunks run in-process, on a local process pool (``run_chunks``, and
``labrig.model.scan.run`` for a whole scan into a file) or on a dask.distributed
cluster (``labrig.model.scan.distributed``), for a library that outgrows one machine.

Every curve's scalar kernel is built once per process (``kernel_of``), before
the workers fork, not once per actuator. A failure on one actuator is recorded with its
error text and the scan goes on. Results are written by the parent only, chunk after
chunk in order (``labrig.model.scan.scan_file``), so the file is the same whatever the
number of workers, and an interrupted scan resumes at its first unfinished chunk.

What is computed per actuator: the quasi-static path under inflation from the
unpressurised state to ``default_end_volume_ml`` (past which no transition can happen),
optionally followed by deflation back to zero, and its transitions
(``labrig.model.actuator.transitions``), the fields of ``labrig model path --json``.
"""

from __future__ import annotations

import contextlib
import hashlib
import math
import os
import resource
import threading
import time
from collections import deque
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from functools import cached_property
from pathlib import Path

import numpy as np

from labrig.errors import InputError
from labrig.model.actuator import jit
from labrig.model.actuator.descent import volume_unit_ml
from labrig.model.actuator.equilibria import Actuator
from labrig.model.actuator.kernel import kernel_of
from labrig.model.actuator.path import quasi_static_path
from labrig.model.actuator.transitions import WINDOW_ML, transitions
from labrig.model.scan.plan import named_library
from labrig.model.segments.curve import SegmentCurve

GENT = "gent"


@dataclass(frozen=True)
class ScanLibrary:
    """The segments a scan combines, in a fixed order (their index is their number in
    the scan file)."""

    label: str  # a named library ("analytical", "paper", "gent", ...) or a folder
    curves: tuple[SegmentCurve, ...]

    @property
    def names(self) -> list[str]:
        return [c.name for c in self.curves]

    @cached_property
    def digest(self) -> str:
        """SHA-256 of the names and tables: a resumed scan must use the same segments."""
        h = hashlib.sha256()
        for c in self.curves:
            h.update(c.name.encode())
            for array in (c.v_ml, c.p_kpa, c.l_mm):
                h.update(np.ascontiguousarray(array, dtype="<f8").tobytes())
        return h.hexdigest()


def load_library(spec: str | None) -> ScanLibrary:
    """``analytical`` (default: the 36 braided segments of the default library, by bare
    name), ``paper``, ``paper-r``, ``calibrated`` or ``si`` (the 36 of that library, by
    prefixed name), ``gent`` (the three membranes of Fig. S1) or a folder of measured
    curves (every ``*.csv`` in it, by file name)."""
    named = named_library(spec)
    if named is not None:
        name, segment_names = named
        if name == GENT:
            from labrig.model.segments.gent import gent_membrane as build
        else:
            from labrig.model.segments.catalog import analytical_segment as build
        from labrig.model.segments.curve_cache import cached_curves

        curves = cached_curves(name, segment_names, lambda: tuple(build(n) for n in segment_names))
        return ScanLibrary(name, curves)
    folder = Path(spec)
    if not folder.is_dir():
        raise InputError(
            f"--library {spec!r}: use 'analytical' (the 36 braided segments of the default "
            "library), 'paper', 'paper-r', 'calibrated' or 'si' (the 36 of that library), 'gent', "
            "or a folder of measured curves (CSV files volume_ml,pressure_kpa,length_mm)"
        )
    from labrig.model.segments.measured import load_csv

    files = sorted(folder.glob("*.csv"))
    if len(files) < 2:
        raise InputError(
            f"--library {spec}: {len(files)} CSV file(s) in the folder; a scan needs at "
            "least two segments"
        )
    return ScanLibrary(str(folder), tuple(load_csv(f, name=f.stem) for f in files))


# --- combinations ------------------------------------------------------------------------
def combination_at(rank: int, n_items: int, k: int) -> tuple[int, ...]:
    """The combination of rank ``rank`` among all k-subsets of range(n_items) in
    lexicographic order (the order of ``itertools.combinations``)."""
    out = []
    x = 0
    for i in range(k):
        while True:
            count = math.comb(n_items - x - 1, k - i - 1)
            if rank < count:
                break
            rank -= count
            x += 1
        out.append(x)
        x += 1
    return tuple(out)


def combinations_between(start: int, stop: int, n_items: int, k: int) -> Iterator[tuple[int, ...]]:
    """Combinations of ranks start..stop-1, without enumerating the ones before."""
    if start >= stop:
        return
    combo = list(combination_at(start, n_items, k))
    for _ in range(stop - start - 1):
        yield tuple(combo)
        i = k - 1
        while combo[i] == n_items - k + i:
            i -= 1
        combo[i] += 1
        for j in range(i + 1, k):
            combo[j] = combo[j - 1] + 1
    yield tuple(combo)


@dataclass(frozen=True)
class Chunk:
    """Combinations of ranks start..stop-1 of n segments; the scan's unit of work."""

    index: int
    start: int
    stop: int
    n: int
    deflate: bool = False


def default_chunk_size(total: int) -> int:
    """About 200 chunks per scan, 16 to 512 actuators each: enough to keep every core
    busy to the end and to lose at most a second or so of work on an interruption."""
    return min(512, max(16, math.ceil(total / 200)))


def make_chunks(n_items: int, n: int, chunk_size: int, *, deflate: bool = False) -> list[Chunk]:
    total = math.comb(n_items, n)
    return [
        Chunk(i, start, min(start + chunk_size, total), n, deflate)
        for i, start in enumerate(range(0, total, chunk_size))
    ]


# --- the pure chunk function -------------------------------------------------------------
TRANSITION_FIELDS = ("direction", "v_ml", "alpha", "beta", "stable", "dE", "dv", "dl", "dp")


@dataclass(frozen=True)
class ChunkResult:
    """One row per transition (actuator rank, segment indices, the transition's fields)
    and one per failed actuator; plain arrays, cheap to pickle."""

    index: int
    n_actuators: int
    actuator: np.ndarray  # (m,) int64 rank of the combination
    segments: np.ndarray  # (m, n) int16
    columns: dict[str, np.ndarray]  # TRANSITION_FIELDS -> (m,)
    failed_actuator: np.ndarray  # (f,) int64
    failed_segments: np.ndarray  # (f, n) int16
    failed_error: tuple[str, ...]
    seconds: float
    peak_rss_mib: float  # of the process that computed it


def scan_actuator(library: ScanLibrary, combo: tuple[int, ...], *, deflate: bool = False):
    """The transitions of the actuator made of segments ``combo`` of ``library``. Each
    curve's scalar kernel is built once per process (``kernel_of``) and shared
    by every actuator the curve is in."""
    actuator = Actuator([library.curves[i] for i in combo])
    return transitions(quasi_static_path(actuator, deflate=deflate))


# An actuator's rows as two arrays: (m, 4) int64 direction, alpha, beta, stable and
# (m, 5) float64 v_ml, dE, dv, dl, dp (the layout ``compiled_path`` returns)
Rows = tuple[np.ndarray, np.ndarray]
_INT_FIELDS = ("direction", "alpha", "beta", "stable")
_FLOAT_FIELDS = ("v_ml", "dE", "dv", "dl", "dp")


def reference_rows(library: ScanLibrary, combo: tuple[int, ...], deflate: bool) -> Rows:
    """An actuator's rows by the reference path (``scan_actuator``)."""
    found = scan_actuator(library, combo, deflate=deflate)
    ints = np.array([[getattr(t, f) for f in _INT_FIELDS] for t in found], dtype=np.int64)
    floats = np.array([[getattr(t, f) for f in _FLOAT_FIELDS] for t in found], dtype=float)
    return ints.reshape(-1, len(_INT_FIELDS)), floats.reshape(-1, len(_FLOAT_FIELDS))


class _CompiledRows:
    """The rows of actuators by ``labrig.model.actuator.compiled_path`` (the same bits
    as the reference, in one compiled call per actuator); an actuator it leaves to the
    reference, or that fails there, goes through ``scan_actuator``, whose rows or error
    are then the actuator's."""

    def __init__(self, library: ScanLibrary) -> None:
        from labrig.model.actuator import compiled_path
        from labrig.model.actuator.descent import FLOW_TOL
        from labrig.model.actuator.path import SCREEN_MARGIN

        self.library = library
        self.kernels = tuple(kernel_of(c) for c in library.curves)
        self.tables = compiled_path.library_tables(self.kernels)
        self.trace = compiled_path.trace_transitions
        self.settings = (SCREEN_MARGIN, FLOW_TOL, WINDOW_ML)

    def __call__(self, combo: tuple[int, ...], deflate: bool) -> Rows:
        try:
            return self.compiled(combo, deflate)
        except Exception:  # a state the compiled path leaves to the reference
            return reference_rows(self.library, combo, deflate)

    def warm(self) -> None:
        """Compile (or load from numba's cache) before the workers fork, so that they
        inherit the machine code instead of each compiling it."""
        with contextlib.suppress(Exception):  # a pair it leaves: compiled all the same
            self.compiled((0, 1), False)

    def compiled(self, combo: tuple[int, ...], deflate: bool) -> Rows:
        """The rows by the compiled path alone (raises where it gives up)."""
        unit = volume_unit_ml([self.kernels[i] for i in combo])
        return self.trace(
            *self.tables, np.array(combo, dtype=np.int64), deflate, unit, *self.settings
        )


def _rows_function(library: ScanLibrary) -> Callable[[tuple[int, ...], bool], Rows]:
    """How a chunk's actuators are solved: compiled whole (``_CompiledRows``) in a
    process that compiles, else the reference (``LABRIG_JIT=python``). A library of
    measured tables also takes the reference: its transitions leave out snaps below the
    tables' resolution (``transitions``), which the compiled path does not know."""
    if not jit.COMPILED or any(c.measured is not None for c in library.curves):
        return lambda combo, deflate: reference_rows(library, combo, deflate)
    rows = _ROWS.get(library)
    if rows is None:
        rows = _ROWS[library] = _CompiledRows(library)
    return rows


_ROWS: dict[ScanLibrary, _CompiledRows] = {}


def solve_actuator(library: ScanLibrary, combo: tuple[int, ...], *, deflate: bool = False) -> Rows:
    """What a chunk computes for one actuator: its rows, by the compiled path where the
    process compiles (``_rows_function``)."""
    return _rows_function(library)(combo, deflate)


def run_chunk(library: ScanLibrary, chunk: Chunk) -> ChunkResult:
    """Every actuator of ``chunk``: chunk in, arrays out (see the module docstring)."""
    started = time.perf_counter()
    n_items = len(library.curves)
    found_ints: list[np.ndarray] = [np.zeros((0, len(_INT_FIELDS)), dtype=np.int64)]
    found_floats: list[np.ndarray] = [np.zeros((0, len(_FLOAT_FIELDS)))]
    ranks: list[int] = []
    combos: list[tuple[int, ...]] = []
    counts: list[int] = []
    failed: list[tuple[int, tuple[int, ...], str]] = []
    solve = _rows_function(library)
    for rank, combo in enumerate(
        combinations_between(chunk.start, chunk.stop, n_items, chunk.n), chunk.start
    ):
        try:
            ints, floats = solve(combo, chunk.deflate)
        except Exception as exc:  # recorded in the file; one actuator never stops a scan
            failed.append((rank, combo, f"{type(exc).__name__}: {exc}"))
            continue
        found_ints.append(ints)
        found_floats.append(floats)
        ranks.append(rank)
        combos.append(combo)
        counts.append(len(ints))
    ints, floats = np.concatenate(found_ints), np.concatenate(found_floats)
    dtypes = {"direction": np.int8, "alpha": np.int8, "beta": np.int8, "stable": np.bool_}
    columns = {name: ints[:, j].astype(dtypes[name]) for j, name in enumerate(_INT_FIELDS)}
    columns |= {name: floats[:, j].copy() for j, name in enumerate(_FLOAT_FIELDS)}
    return ChunkResult(
        index=chunk.index,
        n_actuators=chunk.stop - chunk.start,
        actuator=np.repeat(np.array(ranks, dtype=np.int64), counts),
        segments=np.repeat(np.array(combos, dtype=np.int16).reshape(-1, chunk.n), counts, axis=0),
        columns={name: columns[name] for name in TRANSITION_FIELDS},
        failed_actuator=np.array([f[0] for f in failed], dtype=np.int64),
        failed_segments=np.array([f[1] for f in failed], dtype=np.int16).reshape(-1, chunk.n),
        failed_error=tuple(f[2] for f in failed),
        seconds=time.perf_counter() - started,
        peak_rss_mib=peak_rss_mib(),
    )


def peak_rss_mib() -> float:
    """Peak resident memory of this process (Linux reports KiB, macOS bytes)."""
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    return peak / (1024 * 1024) if os.uname().sysname == "Darwin" else peak / 1024


# --- running chunks on local processes ----------------------------------------------------
_WORKER_LIBRARY: ScanLibrary | None = None


def _init_worker(library: ScanLibrary) -> None:
    import signal

    global _WORKER_LIBRARY
    # Ctrl-C is the parent's to handle: it stops the pool and keeps the file consistent
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    _WORKER_LIBRARY = library
    for curve in library.curves:
        kernel_of(curve)  # built once here, before the first chunk


def _run_in_worker(chunk: Chunk) -> ChunkResult:
    assert _WORKER_LIBRARY is not None
    return run_chunk(_WORKER_LIBRARY, chunk)


class ScanInterrupted(Exception):
    """The scan was asked to stop (``stop`` set, e.g. by Ctrl-C); finished chunks are
    in the file."""


def run_chunks(
    library: ScanLibrary,
    chunks: list[Chunk],
    sink: Callable[[list[ChunkResult]], None],
    *,
    workers: int,
    stop: threading.Event | None = None,
) -> None:
    """Run ``chunks`` and hand every result to ``sink`` in chunk order: a list of the
    results that are ready one after another, which the scan file writes at once.

    At most 2 * workers + 2 chunks are in flight, so memory stays bounded however long
    the scan (results that finish early wait for the slower one before them). When
    ``stop`` is set, ScanInterrupted is raised after the next finished chunk: a stop
    asked for between chunks, not a KeyboardInterrupt raised wherever the main thread
    happens to be (inside a weakref callback of a collection it is swallowed, and the
    scan ran on to the end).
    """

    def check_stop() -> None:
        if stop is not None and stop.is_set():
            raise ScanInterrupted("the scan was stopped; its finished chunks are kept")

    for curve in library.curves:  # built before any fork, so that workers inherit them
        kernel_of(curve)
    solve = _rows_function(library)
    if chunks and isinstance(solve, _CompiledRows):
        solve.warm()  # here, apart from the chunks' time, in one worker or many
    if workers <= 1 or len(chunks) <= 1:
        for chunk in chunks:
            check_stop()
            sink([run_chunk(library, chunk)])
        return
    import multiprocessing

    methods = multiprocessing.get_all_start_methods()
    # fork: the workers inherit the imported modules and the curves (0.5 s saved per
    # worker); elsewhere the library is pickled to each worker once
    context = multiprocessing.get_context("fork" if "fork" in methods else "spawn")
    window = 2 * workers + 2
    todo = iter(chunks)
    with context.Pool(workers, initializer=_init_worker, initargs=(library,)) as pool:
        pending = deque(pool.apply_async(_run_in_worker, (c,)) for c in _take(todo, window))
        while pending:
            ready = [pending.popleft().get()]
            while pending and pending[0].ready():
                ready.append(pending.popleft().get())
            for chunk in _take(todo, len(ready)):
                pending.append(pool.apply_async(_run_in_worker, (chunk,)))
            sink(ready)
            check_stop()


def _take(iterator: Iterator[Chunk], count: int) -> list[Chunk]:
    out = []
    for _ in range(count):
        item = next(iterator, None)
        if item is None:
            break
        out.append(item)
    return out
