"""The live page answers only requests addressed to this machine: a page elsewhere that
rebinds its own host name to 127.0.0.1 (DNS rebinding) gets 421, not the run."""

import http.client
import json

import pytest

from labrig.config.protocol import parse_protocol
from labrig.live.model import BackgroundPrediction
from labrig.live.server import LiveServer
from labrig.live.session import run_info
from labrig.live.state import LiveState

PROTOCOL = """\
name: host check
specimen: {segments: [SI-B46-T20]}
limits: {max_pressure_kpa: 95, max_volume_ml: 10}
steps: [{infuse: {rate_ml_min: 10, volume_ml: 5}}]
"""


@pytest.fixture(scope="module")
def server():
    protocol = parse_protocol(PROTOCOL)
    state = LiveState(run_info(protocol)).start()
    # the prediction is never started: the page's model stays {"ready": false}
    live = LiveServer(state, BackgroundPrediction(protocol)).start()
    yield live
    live.close()
    state.close()


def get(server, host: str | None, path: str = "/api/state", method: str = "GET"):
    address, port = server._server.server_address[:2]
    connection = http.client.HTTPConnection(address, port, timeout=30)
    try:
        connection.putrequest(method, path, skip_host=True)
        if host is not None:
            connection.putheader("Host", host.format(port=port))
        connection.endheaders()
        response = connection.getresponse()
        return response.status, response.read().decode()
    finally:
        connection.close()


@pytest.mark.parametrize(
    "host",
    ["127.0.0.1:{port}", "localhost:{port}", "LOCALHOST:{port}", "[::1]:{port}", "localhost"],
)
def test_requests_to_this_machine_are_served(server, host):
    status, body = get(server, host)
    assert status == 200
    assert set(json.loads(body)) >= {"t_s", "volume_ml", "pressure_kpa", "status"}


@pytest.mark.parametrize(
    ("host", "path", "method"),
    [
        ("evil.example.com", "/api/state", "GET"),
        ("evil.example.com:{port}", "/api/series", "GET"),
        ("127.0.0.1.evil.example.com:{port}", "/", "GET"),
        ("localhost:1", "/api/info", "GET"),
        ("", "/api/state", "GET"),
        (None, "/api/state", "GET"),
        ("evil.example.com:{port}", "/api/state", "HEAD"),
    ],
)
def test_any_other_host_gets_421_and_no_data(server, host, path, method):
    status, body = get(server, host, path, method)
    assert status == 421
    if method == "GET":
        assert body.startswith("421 Misdirected Request: this live view answers only")
        assert "host check" not in body and "{" not in body


@pytest.mark.parametrize("second", ["evil.example.com", "127.0.0.1:{port}"])
def test_two_host_headers_get_421(server, second):
    """A proxy may read the last of two Host headers where this server read the first:
    two are refused, whichever they name."""
    address, port = server._server.server_address[:2]
    connection = http.client.HTTPConnection(address, port, timeout=30)
    try:
        connection.putrequest("GET", "/api/state", skip_host=True)
        connection.putheader("Host", f"127.0.0.1:{port}")
        connection.putheader("Host", second.format(port=port))
        connection.endheaders()
        response = connection.getresponse()
        assert response.status == 421
        assert "host check" not in response.read().decode()
    finally:
        connection.close()
