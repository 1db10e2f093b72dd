"""A whole scan into a file: the chunks of ``labrig.model.scan.scan`` computed on local
processes and appended in order to a ``ScanFile``, resumable after an interruption.

Its own module because it stands above both: the scan file needs the chunks' layout,
and the chunks need nothing of the file.
"""

from __future__ import annotations

import math
import threading
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from labrig.errors import InputError
from labrig.model.scan.scan import (
    MAX_N,
    ChunkResult,
    ScanLibrary,
    default_chunk_size,
    default_workers,
    peak_rss_mib,
    run_chunks,
)
from labrig.model.scan.scan_file import ScanFile


@dataclass(frozen=True)
class ScanProgress:
    actuators_done: int
    actuators_total: int
    chunks_done: int
    chunks_total: int


def run_scan(
    library: ScanLibrary,
    n: int,
    out: Path,
    *,
    workers: int | None = None,
    resume: bool = False,
    deflate: bool = False,
    chunk_size: int | None = None,
    progress: Callable[[ScanProgress], None] | None = None,
    stop: threading.Event | None = None,
) -> Path:
    """Scan every combination of ``n`` segments of ``library`` into ``out`` (HDF5).

    With ``resume`` the file must hold an interrupted scan of the same library, n and
    ``deflate``; its finished chunks are kept and the rest computed. Setting ``stop``
    ends the scan after the chunk in hand (ScanInterrupted). On any exception the file
    is closed with every finished chunk in it.
    """
    if not 2 <= n <= min(MAX_N, len(library.curves)):
        raise InputError(
            f"--n {n}: choose 2..{min(MAX_N, len(library.curves))} "
            f"({len(library.curves)} segments in the library)"
        )
    workers = default_workers() if workers is None else workers
    if workers < 1:
        raise InputError(f"--workers {workers}: must be at least 1")
    total = math.comb(len(library.curves), n)
    if resume:
        if not out.is_file():
            raise InputError(f"--resume: {out} does not exist; start the scan without --resume")
        scan = ScanFile.resume(out, library, n, deflate=deflate)
    else:
        if out.exists():
            raise InputError(
                f"--out {out}: the file exists; --resume continues it, or remove it first"
            )
        if not out.parent.is_dir():
            raise InputError(f"--out {out}: the folder {out.parent} does not exist")
        size = default_chunk_size(total) if chunk_size is None else chunk_size
        scan = ScanFile.create(out, library, n, chunk_size=size, deflate=deflate)
    chunks = scan.pending_chunks()
    done = {"chunks": scan.chunks_done, "actuators": total - sum(c.stop - c.start for c in chunks)}

    def sink(result: ChunkResult) -> None:
        scan.append(result)
        done["chunks"] += 1
        done["actuators"] += result.n_actuators
        if progress is not None:
            progress(ScanProgress(done["actuators"], total, done["chunks"], scan.n_chunks))

    if progress is not None:
        progress(ScanProgress(done["actuators"], total, done["chunks"], scan.n_chunks))
    try:
        run_chunks(library, chunks, sink, workers=workers, stop=stop)
    finally:
        scan.close(workers=workers, parent_peak_rss_mib=peak_rss_mib())
    return out
