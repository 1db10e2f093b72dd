"""A whole scan into a file: the chunks of ``labrig.model.scan.scan`` computed on local
processes or on a dask.distributed cluster (``labrig.model.scan.distributed``) and
appended in order to a ``ScanFile``, resumable after an interruption.

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
from labrig.model.scan.plan import MAX_N, default_workers
from labrig.model.scan.scan import (
    ChunkResult,
    ScanLibrary,
    default_chunk_size,
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
    scheduler: str | None = None,
) -> Path:
    """Scan every combination of ``n`` segments of ``library`` into ``out`` (HDF5).

    With ``resume`` the file must hold an interrupted scan of the same library, n and
    ``deflate``; its finished chunks are kept and the rest computed. Setting ``stop``
    ends the scan after the chunk in hand (ScanInterrupted). On any exception the file
    is closed with every finished chunk in it. With ``scheduler`` (``tcp://host:port``)
    the chunks run on that dask.distributed cluster instead of ``workers`` local
    processes; the file is the same.
    """
    if not 2 <= n <= min(MAX_N, len(library.curves)):
        raise InputError(
            f"--n {n}: choose 2..{min(MAX_N, len(library.curves))} "
            f"({len(library.curves)} segments in the library)"
        )
    if scheduler is not None and workers is not None:
        raise InputError(
            "--workers and --scheduler: choose one (--workers counts local processes; a "
            "cluster's size is its workers')"
        )
    workers = default_workers() if workers is None else workers
    if workers < 1:
        raise InputError(f"--workers {workers}: must be at least 1")
    check_out(out, resume=resume)
    options = dict(resume=resume, deflate=deflate, chunk_size=chunk_size, progress=progress)
    if scheduler is None:
        _scan_into(library, n, out, workers=workers, client=None, stop=stop, **options)
        return out
    from labrig.model.scan.distributed import cluster_threads, connect

    client = connect(scheduler)  # before the file is touched: a bad address changes nothing
    try:
        workers = cluster_threads(client)
        _scan_into(library, n, out, workers=workers, client=client, stop=stop, **options)
    finally:
        client.close()
    return out


def check_out(out: Path, *, resume: bool) -> None:
    """InputError unless ``out`` can take the scan: a new file in an existing folder, or
    with ``resume`` an existing one (``run_scan`` checks it; the command also checks it
    first, before it starts compiling)."""
    if resume and not out.is_file():
        raise InputError(f"--resume: {out} does not exist; start the scan without --resume")
    if not resume:
        if out.exists():
            raise InputError(
                f"--out {out}: the file exists; --resume continues it, or remove it first"
            )
        if not out.parent.is_dir():
            raise InputError(f"--out {out}: the folder {out.parent} does not exist")


def _scan_into(
    library, n, out, *, resume, deflate, chunk_size, progress, stop, workers, client
) -> None:
    """``run_scan`` once its arguments are checked: open the file, run what is pending
    locally (``client`` None) or on the cluster, close the file."""
    total = math.comb(len(library.curves), n)
    if resume:
        scan = ScanFile.resume(out, library, n, deflate=deflate)
    else:
        size = default_chunk_size(total) if chunk_size is None else chunk_size
        scan = ScanFile.create(out, library, n, chunk_size=size, deflate=deflate)
    chunks = scan.pending_chunks()
    done = {"chunks": scan.chunks_done, "actuators": total - sum(c.stop - c.start for c in chunks)}

    def sink(results: list[ChunkResult]) -> None:
        scan.append(results)
        for result in results:  # each chunk told, as if written one by one
            done["chunks"] += 1
            done["actuators"] += result.n_actuators
            if progress is not None:
                progress(ScanProgress(done["actuators"], total, done["chunks"], scan.n_chunks))

    try:
        if progress is not None:
            progress(ScanProgress(done["actuators"], total, done["chunks"], scan.n_chunks))
        if client is None:
            run_chunks(library, chunks, sink, workers=workers, stop=stop)
        else:
            from labrig.model.scan.distributed import run_chunks_on_cluster

            run_chunks_on_cluster(client, library, chunks, sink, stop=stop)
    finally:
        scan.close(workers=workers, parent_peak_rss_mib=peak_rss_mib())
