"""GET /api/state during a simulated run (``labrig run --live``): the contract's fields,
a volume that grows between two requests, a final status after the run; and clients
that stall or vanish cost the run nothing (the run file keeps every sample, and is the
file the same run records without a page)."""

from __future__ import annotations

import socket
import urllib.error
import urllib.request

import h5py
import numpy as np
import pytest
from support.liverun import PROTOCOL, get, poll_until

from labrig.cli import main
from labrig.live.state import FINAL_STATUSES, STATE_FIELDS


def stalled_clients(url: str, n: int) -> list[socket.socket]:
    """Connections that send half a request and never read: a hung browser."""
    host, port = url.split("//")[1].strip("/").split(":")
    clients = []
    for _ in range(n):
        s = socket.create_connection((host, int(port)), timeout=5)
        s.sendall(b"GET /api/series?pressure=0 HTTP/1.1\r\nHost: x\r\n")
        clients.append(s)
    return clients


def test_state_during_and_after_a_run(live_run):
    # paced at 20x: 5.8 s of wall time for its 116 s, running all along
    run = live_run("--live", "--live-hold", "5", speed=20)
    hung = stalled_clients(run.url, 5)
    vanished = socket.create_connection(run.url.split("//")[1].strip("/").split(":"), timeout=5)
    vanished.sendall(b"GET /api/series?pressure=0 HTTP/1.1\r\nHost: x\r\n\r\n")
    vanished.close()  # gone before the answer

    state = get(run.url + "api/state")
    assert tuple(state) == STATE_FIELDS
    assert_read_only(run.url)
    first = poll_until(
        lambda: (
            (s := get(run.url + "api/state"))["status"] == "running"
            and (s["volume_ml"] or 0) > 0.5
            and s
        ),
        "the pump to have moved",
    )
    # the camera's lengths reach the page on their own (a busy host may show a volume
    # before the first length): the state with both
    second = poll_until(
        lambda: (
            (s := get(run.url + "api/state"))["volume_ml"] > first["volume_ml"]
            and s["length_mm"] is not None
            and s
        ),
        "a larger volume and a length",
    )
    assert second["volume_ml"] > first["volume_ml"]
    assert second["repetitions"] == 2 and second["repetition"] in (1, 2)
    assert second["pressure_kpa"] is not None and second["length_mm"] is not None

    final = poll_until(
        lambda: (s := get(run.url + "api/state"))["status"] in FINAL_STATUSES and s,
        "the final status",
    )
    assert final["status"] == "complete", run.lines[-5:]
    assert tuple(final) == STATE_FIELDS
    assert run.wait() == 0
    for s in hung:
        s.close()

    # every pressure sample of every repetition is in the file: no gap from the page
    with h5py.File(run.out, "r") as f:
        for rep in ("rep_01", "rep_02"):
            t = f[f"entry/repetitions/{rep}/pressure/time"][:]
            assert len(t) > 50_000
            assert np.allclose(np.diff(t), 1e-3)
    # and the file is the one the same run records with no page at all (same seed:
    # the simulated rig's data do not depend on the host, nor on the pace), recorded
    # unpaced in this process, where labrig is imported already: the command's own
    # process is not what is compared
    reference = run.out.with_name("no_page.h5")
    with pytest.raises(SystemExit) as exited:
        main(["run", str(PROTOCOL), "--sim", "--out", str(reference)])
    assert exited.value.code == 0
    assert logs(run.out) == logs(reference)


def logs(path) -> dict[str, bytes]:
    """Every logged series of a run file, as bytes."""
    out = {}
    with h5py.File(path, "r") as f:
        reps = f["entry/repetitions"]
        for rep in (name for name in reps if name.startswith("rep_")):
            for log in reps[rep]:
                for field in reps[rep][log]:
                    out[f"{rep}/{log}/{field}"] = reps[rep][log][field][:].tobytes()
    return out


def assert_read_only(url: str) -> None:
    """Only GET is answered, and only the page's own files."""
    request = urllib.request.Request(url + "api/state", data=b"{}", method="POST")
    try:
        urllib.request.urlopen(request, timeout=10)
        raise AssertionError("a POST was answered")
    except urllib.error.HTTPError as exc:
        assert exc.code == 501
    try:
        urllib.request.urlopen(url + "static/../server.py", timeout=10)
        raise AssertionError("a file outside the page was served")
    except urllib.error.HTTPError as exc:
        assert exc.code == 404
    assert get(url + "api/info")["segments"] == ["SI-B48-T30", "SI-B50-T20"]
