"""The chunks of a scan on a dask.distributed cluster (``labrig model scan --scheduler``).

The same pure chunk function as the local pool (``labrig.model.scan.scan.run_chunk``):
the library is scattered to every worker once, chunks are mapped onto it, and the
results come back to the client, which alone hands them to the sink (the scan file) in
chunk order. So the file is the very one a local scan writes, and Ctrl-C and
``--resume`` behave as they do locally: a stop is checked after each result, and the
chunks still in flight are cancelled.

dask.distributed is an optional dependency (``pip install 'labrig[cluster]'``); it is
imported only here, only when a scheduler is named. Starting and sizing a cluster is
left to dask's own commands (docs/how-to/dask-scan.md).
"""

from __future__ import annotations

import threading
from collections import deque
from collections.abc import Callable
from concurrent.futures import CancelledError

from labrig.errors import InputError, LabrigError
from labrig.model.scan.scan import Chunk, ChunkResult, ScanInterrupted, ScanLibrary, run_chunk

# how long to wait for a scheduler to answer, and for a first worker to join it
CONNECT_TIMEOUT_S = 20.0
WORKER_TIMEOUT_S = 60.0


class ClusterLost(LabrigError):
    """The cluster stopped answering or lost the workers of a chunk; the finished chunks
    are in the file, and ``--resume`` continues it (on a cluster or locally)."""


def _labrig_version() -> str:
    from labrig._version import __version__

    return __version__


def connect(address: str):
    """A client of the scheduler at ``address`` (``tcp://host:port``) with at least one
    worker, every worker running this labrig version; InputError otherwise (one line)."""
    try:
        from distributed import Client
    except ImportError:
        raise InputError(
            f"--scheduler {address}: needs dask.distributed; pip install 'labrig[cluster]'"
        ) from None
    if "://" not in address:
        raise InputError(f"--scheduler {address}: give the address as tcp://HOST:PORT")
    try:
        client = Client(address, timeout=CONNECT_TIMEOUT_S, set_as_default=False)
    except (OSError, TimeoutError) as exc:
        raise InputError(
            f"--scheduler {address}: no scheduler answered in {CONNECT_TIMEOUT_S:.0f} s "
            f"({type(exc).__name__}); start one with `dask scheduler` (docs/how-to/dask-scan.md)"
        ) from None
    try:
        try:
            client.wait_for_workers(1, timeout=WORKER_TIMEOUT_S)
        except TimeoutError:
            raise InputError(
                f"--scheduler {address}: no worker joined in {WORKER_TIMEOUT_S:.0f} s; "
                f"start workers with `dask worker {address}` (docs/how-to/dask-scan.md)"
            ) from None
        ours = _labrig_version()
        versions = client.run(_labrig_version)
        other = {w: v for w, v in versions.items() if v != ours}
        if other:
            worker, version = next(iter(other.items()))
            raise InputError(
                f"--scheduler {address}: worker {worker} runs labrig {version}, this client "
                f"{ours}; install the same labrig on every worker"
            )
    except BaseException:
        client.close()
        raise
    return client


def cluster_threads(client) -> int:
    """The threads of every worker: the chunks that can run at once."""
    return sum(w["nthreads"] for w in client.scheduler_info()["workers"].values())


def run_chunks_on_cluster(
    client,
    library: ScanLibrary,
    chunks: list[Chunk],
    sink: Callable[[list[ChunkResult]], None],
    *,
    stop: threading.Event | None = None,
) -> None:
    """Run ``chunks`` on the cluster of ``client``; every result to ``sink`` in chunk
    order (a list of one). At most 2 * threads + 2 chunks are in flight (as on the local
    pool; threads of the workers there are at the time), so the client's and the
    workers' memory stays bounded however long the scan. ``stop`` set:
    ScanInterrupted after the next result, the rest cancelled. A scheduler gone or a
    chunk that killed its workers (dask retries it on others first): ClusterLost."""
    from distributed import KilledWorker

    if not chunks:
        return
    # one copy per worker, sent once (a worker that joins later gets it from a peer):
    # chunks refer to it by its key
    shared = client.scatter(library, broadcast=True)
    todo = iter(chunks)
    pending: deque = deque()

    def fill() -> None:
        """Map chunks up to the window of the cluster as it is now (workers may come)."""
        wanted = 2 * cluster_threads(client) + 2 - len(pending)
        more = [c for _, c in zip(range(max(wanted, 0)), todo, strict=False)]
        pending.extend(client.map(run_chunk, [shared] * len(more), more, pure=False))

    fill()
    try:
        while pending:
            try:
                result = pending.popleft().result()
            except (OSError, CancelledError, KilledWorker) as exc:
                # OSError: the connection (CommClosedError) or a timeout
                raise ClusterLost(
                    f"the cluster at {client.scheduler.address} stopped the scan "
                    f"({type(exc).__name__}: {exc}); the finished chunks are kept, the "
                    "same command with --resume continues it"
                ) from None
            fill()
            sink([result])
            if stop is not None and stop.is_set():
                raise ScanInterrupted("the scan was stopped; its finished chunks are kept")
    finally:
        if pending:
            client.cancel(list(pending))
