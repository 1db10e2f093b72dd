"""Tabulated segments kept between processes, as numba keeps the compiled solver: a
braided segment is an Ogden membrane solved at every volume of its table, and a scan's
36 took more CPU than the actuators of a whole n = 3 scan (3.5 s against 2.6 s;
tests/benchmarks/bench_scan_wall.py); a single command (``labrig model path``, a run's
dry run and simulated specimen) spent most of its time importing scipy's solvers and
tabulating its two segments. Each named library (a scan's) and each library segment
(``catalog.analytical_segment``) is kept in a file of its own.

A file holds each segment's name, source, V0 and its three tables as they were
tabulated (float64, so the tables and everything computed from them are the same bits
as freshly built: a scan file's library digest checks it on a resume), and the pieces
of each curve's PCHIP that the solver's kernels read (``PchipPieces``), so that a warm
scan never imports scipy's interpolation to compute them again. It is named by a hash
of what the tables depend on: the segment names, every file of
``labrig.model.segments`` (the code and data that tabulate them) and the versions of
Python, numpy and scipy; any change to those names another file, and the old one is
removed when the new one is written. The folder is ``$LABRIG_CACHE_DIR`` if set, else
``__pycache__`` beside this module where that is writable (numba's choice for its own
cache), else the user's cache folder. A file that cannot be read or written is rebuilt
or skipped: the cache only ever saves time.
"""

from __future__ import annotations

import hashlib
import importlib.metadata
import os
import platform
import tempfile
from collections.abc import Callable, Sequence
from pathlib import Path

import numpy as np

from labrig.model.segments.curve import PchipPieces, SegmentCurve

CACHE_VARIABLE = "LABRIG_CACHE_DIR"
SEGMENTS_PACKAGE = Path(__file__).resolve().parent
_FORMAT = "labrig curves 3"
_PREFIX = "curves-"
_KEY_CHARACTERS = 32


def cache_folder() -> Path:
    """Where the tables are kept (see the module docstring)."""
    chosen = os.environ.get(CACHE_VARIABLE)
    if chosen:
        return Path(chosen)
    beside = Path(__file__).resolve().parent / "__pycache__"
    if os.access(beside if beside.is_dir() else beside.parent, os.W_OK):
        return beside
    home = os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache"
    return Path(home) / "labrig"


def _key(label: str, names: Sequence[str]) -> str:
    """A hash of everything the tables of ``names`` depend on."""
    h = hashlib.sha256()
    for part in (_FORMAT, label, *names, platform.python_version(), np.__version__):
        h.update(part.encode() + b"\0")
    # the installed version from its metadata: importing scipy to read it costs a run
    h.update(importlib.metadata.version("scipy").encode() + b"\0")
    h.update(_package_digest().encode())
    return h.hexdigest()


def _package_digest() -> str:
    """The hash of every file of ``SEGMENTS_PACKAGE``, read again only when a file's
    size or modification time changed: a command asks for each of its segments."""
    files = sorted(
        path
        for path in SEGMENTS_PACKAGE.rglob("*")
        if path.is_file() and "__pycache__" not in path.parts
    )
    stats = [(path, path.stat()) for path in files]
    stamp = tuple((path, stat.st_mtime_ns, stat.st_size) for path, stat in stats)
    digest = _PACKAGE_DIGESTS.get(stamp)
    if digest is None:
        h = hashlib.sha256()
        for path in files:
            h.update(path.relative_to(SEGMENTS_PACKAGE).as_posix().encode() + b"\0")
            h.update(path.read_bytes())
        digest = _PACKAGE_DIGESTS[stamp] = h.hexdigest()
    return digest


_PACKAGE_DIGESTS: dict[tuple, str] = {}


def cached_curves(
    label: str, names: Sequence[str], build: Callable[[], tuple[SegmentCurve, ...]]
) -> tuple[SegmentCurve, ...]:
    """The curves of ``label`` (a library, or one segment: segments ``names``, in
    order; a label names files, so letters, digits and ``-_.`` only), read from the
    cache, or built by ``build`` and stored there for the next process; the same
    objects for every call of the process (each curve's kernel is built once per
    curve)."""
    key = _key(label, names)
    curves = _IN_PROCESS.get(key)
    if curves is None:
        path = cache_folder() / f"{_PREFIX}{label}-{key[:_KEY_CHARACTERS]}.npz"
        curves = _read(path, key, names)
        if curves is None:
            curves = build()
            _write(path, label, key, curves)
        _IN_PROCESS[key] = curves
    return curves


_IN_PROCESS: dict[str, tuple[SegmentCurve, ...]] = {}


def _read(path: Path, key: str, names: Sequence[str]) -> tuple[SegmentCurve, ...] | None:
    try:
        with np.load(path, allow_pickle=False) as stored:
            if str(stored["key"]) != key or list(stored["names"]) != list(names):
                return None
            return tuple(
                SegmentCurve.with_pieces(
                    PchipPieces(
                        stored[f"x_{i}"],
                        stored[f"p_coefficients_{i}"],
                        stored[f"l_coefficients_{i}"],
                        float(stored["start_slope_kpa_per_ml"][i]),
                        float(stored["end_slope_kpa_per_ml"][i]),
                    ),
                    name=str(name),
                    v_ml=stored[f"v_ml_{i}"],
                    p_kpa=stored[f"p_kpa_{i}"],
                    l_mm=stored[f"l_mm_{i}"],
                    V0_ml=float(stored["V0_ml"][i]),
                    source=str(stored["source"][i]),
                )
                for i, name in enumerate(stored["names"])
            )
    except (OSError, KeyError, ValueError):  # none yet, or damaged: built again
        return None


def _write(path: Path, label: str, key: str, curves: tuple[SegmentCurve, ...]) -> None:
    """Store the tables, and remove the library's files of other keys (no longer read)."""
    if any(c.measured is not None for c in curves):
        return  # a measured table's import record is not kept here
    arrays = {
        "key": np.array(key),
        "names": np.array([c.name for c in curves]),
        "source": np.array([c.source for c in curves]),
        "V0_ml": np.array([c.V0_ml for c in curves], dtype=float),
        "start_slope_kpa_per_ml": np.array([c.pieces.start_slope_kpa_per_ml for c in curves]),
        "end_slope_kpa_per_ml": np.array([c.pieces.end_slope_kpa_per_ml for c in curves]),
    }
    for i, c in enumerate(curves):
        arrays |= {f"v_ml_{i}": c.v_ml, f"p_kpa_{i}": c.p_kpa, f"l_mm_{i}": c.l_mm}
        arrays |= {
            f"x_{i}": c.pieces.x,
            f"p_coefficients_{i}": c.pieces.p_coefficients,
            f"l_coefficients_{i}": c.pieces.l_coefficients,
        }
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        handle, temporary = tempfile.mkstemp(dir=path.parent, suffix=".npz")
    except OSError:  # a read-only folder: the next scan builds them again
        return
    try:
        # written whole, then renamed: a scan reading at the same time sees all or nothing
        with os.fdopen(handle, "wb") as out:
            np.savez(out, **arrays)
        os.replace(temporary, path)
    except OSError:  # a full disk
        Path(temporary).unlink(missing_ok=True)
        return
    # of code since changed (a key's length of any characters: ``label-*`` would
    # match another label that begins with this one)
    for older in path.parent.glob(f"{_PREFIX}{label}-{'?' * _KEY_CHARACTERS}.npz"):
        if older != path:
            older.unlink(missing_ok=True)
