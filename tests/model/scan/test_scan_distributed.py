"""Scans on a real dask.distributed cluster: a scheduler and two worker processes started
as a user starts them (``dask scheduler``, ``dask worker``) on 127.0.0.1, over TCP. The
file must be the local scan's, bit for bit, also after a stop and ``--resume``; a bad
address or a missing extra is one line, and no file is made."""

import contextlib
import json
import subprocess
import sys
import threading
import time

import pytest
from support.scan_helpers import SMALL, assert_same_contents, small_library

from labrig.cli import main
from labrig.errors import InputError
from labrig.model.scan import distributed as cluster_engine
from labrig.model.scan.run import run_scan
from labrig.model.scan.scan import ScanInterrupted
from labrig.model.scan.scan_file import read_scan
from labrig.model.segments.catalog import analytical_segment
from labrig.model.segments.measured import write_csv

pytest.importorskip("distributed", reason="the cluster extra: pip install -e '.[test]'")
pytestmark = pytest.mark.slow


def _dask(*args, log):
    """``dask scheduler|worker ...`` of this interpreter's environment."""
    return subprocess.Popen(
        [sys.executable, "-m", f"distributed.cli.dask_{args[0]}", *args[1:]],
        stdout=log,
        stderr=subprocess.STDOUT,
    )


def _stop(process):
    process.terminate()
    try:
        process.wait(timeout=30)
    except subprocess.TimeoutExpired:
        process.kill()
        process.wait()


def _scheduler_address(info, process, timeout_s=60):
    """The address the scheduler wrote to ``info``: the file appears before its JSON is
    complete (a busy host once read it empty), so it is read until it parses."""
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        assert process.poll() is None, "the scheduler exited; see cluster.log"
        with contextlib.suppress(FileNotFoundError, json.JSONDecodeError, KeyError):
            return json.loads(info.read_text())["address"]
        time.sleep(0.1)
    raise AssertionError(f"no scheduler address in {info} within {timeout_s} s")


@contextlib.contextmanager
def local_cluster(folder, n_workers):
    """(address, processes) of a scheduler with ``n_workers`` single-threaded worker
    processes; every process stopped at the end."""
    from distributed import Client

    log = (folder / "cluster.log").open("w")
    info = folder / "scheduler.json"
    processes = [
        _dask(
            "scheduler",
            "--host",
            "127.0.0.1",
            "--port",
            "0",
            "--no-dashboard",
            "--scheduler-file",
            str(info),
            log=log,
        )
    ]
    try:
        address = _scheduler_address(info, processes[0])
        assert address.startswith("tcp://127.0.0.1:")
        processes.append(
            _dask(
                "worker",
                address,
                "--nworkers",
                str(n_workers),
                "--nthreads",
                "1",
                "--no-dashboard",
                "--local-directory",
                str(folder),
                log=log,
            )
        )
        with Client(address, timeout=30) as client:
            client.wait_for_workers(n_workers, timeout=120)
        yield address, processes
    finally:
        for process in reversed(processes):
            _stop(process)
        log.close()


@pytest.fixture(scope="module")
def scheduler(tmp_path_factory):
    """The address of a scheduler with two single-threaded worker processes."""
    with local_cluster(tmp_path_factory.mktemp("cluster"), 2) as (address, _):
        yield address


def test_a_cluster_scan_is_the_local_scan(tmp_path, scheduler):
    library = small_library()
    local, cluster = tmp_path / "local.h5", tmp_path / "cluster.h5"
    run_scan(library, 3, local, workers=1, chunk_size=7, deflate=True)
    run_scan(library, 3, cluster, scheduler=scheduler, chunk_size=7, deflate=True)
    assert_same_contents(local, cluster)
    data = read_scan(cluster)
    assert data.complete and data.actuators_done == 56
    assert data.workers == 2  # the cluster's threads
    # computed in the worker processes, not in this one
    assert data.worker_peak_rss_mib > 10


def test_a_stopped_cluster_scan_resumes_to_the_local_file(tmp_path, scheduler):
    library = small_library()
    whole, cut = tmp_path / "whole.h5", tmp_path / "cut.h5"
    run_scan(library, 3, whole, workers=1, chunk_size=4)
    stop = threading.Event()

    def stop_after_three_chunks(progress):
        if progress.chunks_done == 3:
            stop.set()

    with pytest.raises(ScanInterrupted):
        run_scan(
            library,
            3,
            cut,
            scheduler=scheduler,
            chunk_size=4,
            progress=stop_after_three_chunks,
            stop=stop,
        )
    partial = read_scan(cut)
    assert not partial.complete and partial.actuators_done == 12
    seen = []
    run_scan(library, 3, cut, scheduler=scheduler, resume=True, progress=seen.append)
    assert seen[0].chunks_done == 3 and seen[-1].actuators_done == 56
    assert_same_contents(whole, cut)


def test_the_command_line_scan_on_a_cluster(tmp_path, scheduler, capsys):
    folder = tmp_path / "lib"
    folder.mkdir()
    for name in SMALL[:4]:
        write_csv(analytical_segment(name), folder / f"{name}.csv")
    out = tmp_path / "pairs.h5"
    argv = ["model", "scan", "--n", "2", "--library", str(folder), "--out", str(out)]
    with pytest.raises(SystemExit) as exited:
        main([*argv, "--scheduler", scheduler])
    _, err = capsys.readouterr()
    assert exited.value.code == 0, err
    data = read_scan(out)
    assert data.complete and data.actuators_done == 6 and data.workers == 2


def test_a_lost_scheduler_keeps_the_finished_chunks_for_resume(tmp_path, scheduler):
    library = small_library()
    out = tmp_path / "cut.h5"
    with local_cluster(tmp_path, 1) as (address, processes):

        def kill_the_scheduler_after_two_chunks(progress):
            if progress.chunks_done == 2:
                processes[0].kill()
                processes[0].wait()

        with pytest.raises(cluster_engine.ClusterLost, match="--resume continues it"):
            run_scan(
                library,
                3,
                out,
                scheduler=address,
                chunk_size=4,
                progress=kill_the_scheduler_after_two_chunks,
            )
    assert read_scan(out).actuators_done == 8
    run_scan(library, 3, out, scheduler=scheduler, resume=True)
    whole = tmp_path / "whole.h5"
    run_scan(library, 3, whole, workers=1, chunk_size=4)
    assert_same_contents(whole, out)


def _one_line_error(argv, capsys):
    with pytest.raises(SystemExit) as exited:
        main(argv)
    _, err = capsys.readouterr()
    assert exited.value.code == 2
    assert len(err.strip().splitlines()) == 1, err
    return err


def test_no_scheduler_at_the_address_is_one_line(tmp_path, capsys, monkeypatch):
    monkeypatch.setattr(cluster_engine, "CONNECT_TIMEOUT_S", 2.0)
    out = tmp_path / "a.h5"
    argv = ["model", "scan", "--n", "2", "--out", str(out)]
    err = _one_line_error([*argv, "--scheduler", "tcp://127.0.0.1:9"], capsys)
    assert "no scheduler answered" in err and "dask scheduler" in err
    assert not out.exists()
    err = _one_line_error([*argv, "--scheduler", "tcp://127.0.0.1:9", "--workers", "2"], capsys)
    assert "choose one" in err


def test_without_the_cluster_extra_the_error_says_how_to_install_it(monkeypatch):
    monkeypatch.setitem(sys.modules, "distributed", None)  # import distributed fails
    with pytest.raises(InputError, match=r"pip install 'labrig\[cluster\]'"):
        cluster_engine.connect("tcp://127.0.0.1:8786")
