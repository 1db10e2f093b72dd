"""The live page's HTTP server: the standard library's, on 127.0.0.1, read-only.

``ThreadingHTTPServer`` in a daemon thread: each browser connection has its own thread,
so a slow or vanished browser holds up only that thread (and a socket timeout ends it),
never the run. Every request reads a snapshot that ``labrig.live.state.LiveState``
publishes; nothing a request does can reach the runner or the devices, and only GET
(and HEAD) are answered.

Every request must name this server in its ``Host`` header (localhost, 127.0.0.1, [::1]
or the bound address, with or without the port), else 421 Misdirected Request: a web
page on another site that points its own host name at 127.0.0.1 (DNS rebinding) would
otherwise read the run through the visitor's browser, as if from the same origin.

Routes: ``/`` the page; ``/static/<file>`` its script and style (package data: the page
works offline, with no CDN); ``/api/state`` the latest state (fixed fields, a contract);
``/api/series?pressure=N&length=M`` the points since those indices, with the detected
transitions, the time left and why a run stopped; ``/api/info`` the run's fixed facts;
``/api/model`` the model's prediction (``{"ready": false}`` while it is computed).
"""

from __future__ import annotations

import json
import math
import threading
from dataclasses import asdict
from http import HTTPStatus
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from importlib import resources
from urllib.parse import parse_qs, urlsplit

from labrig.errors import InputError
from labrig.live.state import LiveState

STATIC_TYPES = {
    "index.html": "text/html; charset=utf-8",
    "live.js": "text/javascript; charset=utf-8",
    "live.css": "text/css; charset=utf-8",
}
HOST = "127.0.0.1"
CLIENT_TIMEOUT_S = 10.0  # a browser that stops reading loses its connection after this


def _static(name: str) -> bytes:
    return resources.files("labrig.live").joinpath("static", name).read_bytes()


def _clean(value):
    """JSON has no NaN: non-finite numbers become null."""
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if isinstance(value, dict):
        return {k: _clean(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_clean(v) for v in value]
    return value


class _Handler(BaseHTTPRequestHandler):
    server_version = "labrig-live"
    timeout = CLIENT_TIMEOUT_S

    # set on the subclass made per server
    state: LiveState
    model: object  # has .json

    def do_HEAD(self) -> None:
        self._answer(head=True)

    def do_GET(self) -> None:
        self._answer(head=False)

    def _host_allowed(self) -> bool:
        hosts = self.headers.get_all("Host") or []
        if len(hosts) != 1:  # none, or two that a proxy and this server might read apart
            return False
        host = hosts[0]
        port = str(self.server.server_address[1])
        names = {"localhost", "127.0.0.1", "[::1]", self.server.server_address[0]}
        allowed = names | {f"{name}:{port}" for name in names}
        return host.strip().lower() in allowed

    def _answer(self, head: bool) -> None:
        if not self._host_allowed():
            body = (
                "421 Misdirected Request: this live view answers only requests addressed "
                f"to localhost or 127.0.0.1 (port {self.server.server_address[1]}), not to "
                "another host name\n"
            ).encode()
            self.send_response(HTTPStatus.MISDIRECTED_REQUEST)
            self.send_header("Content-Type", "text/plain; charset=utf-8")
            self.send_header("Content-Length", str(len(body)))
            self.end_headers()
            if not head:
                self.wfile.write(body)
            return
        url = urlsplit(self.path)
        route = url.path
        if route in ("/", "/index.html"):
            self._send(_static("index.html"), STATIC_TYPES["index.html"], head)
        elif route.startswith("/static/") and route[len("/static/") :] in STATIC_TYPES:
            name = route[len("/static/") :]
            self._send(_static(name), STATIC_TYPES[name], head)
        elif route == "/api/state":
            self._json(self.state.state(), head)
        elif route == "/api/series":
            query = parse_qs(url.query)
            try:
                since_p = int(query.get("pressure", ["0"])[0])
                since_l = int(query.get("length", ["0"])[0])
            except ValueError:
                self.send_error(HTTPStatus.BAD_REQUEST, "pressure and length are indices")
                return
            self._json(self.state.series_since(since_p, since_l), head)
        elif route == "/api/info":
            self._json(asdict(self.state.info), head)
        elif route == "/api/model":
            self._json(self.model.json, head)
        else:
            self.send_error(HTTPStatus.NOT_FOUND)

    def _json(self, payload, head: bool) -> None:
        body = json.dumps(_clean(payload), allow_nan=False, separators=(",", ":")).encode()
        self._send(body, "application/json", head)

    def _send(self, body: bytes, content_type: str, head: bool) -> None:
        self.send_response(HTTPStatus.OK)
        self.send_header("Content-Type", content_type)
        self.send_header("Content-Length", str(len(body)))
        self.send_header("Cache-Control", "no-store")
        self.end_headers()
        if not head:
            self.wfile.write(body)

    def log_message(self, format, *args) -> None:
        """Quiet: the terminal shows the run, not every poll."""


class _Server(ThreadingHTTPServer):
    daemon_threads = True
    # a page opens several connections at once (page, script, style, polls), and a few
    # pages may watch one run: room for them while a busy host accepts late (default 5)
    request_queue_size = 64

    def handle_error(self, request, client_address) -> None:
        """A browser that went away mid-reply is not an error worth a traceback."""


class LiveServer:
    """Serves ``state`` (and ``model``, anything with a ``json`` dict) on 127.0.0.1.
    ``port`` 0 picks a free port; ``url`` says which."""

    def __init__(self, state: LiveState, model, port: int = 0) -> None:
        handler = type("LiveHandler", (_Handler,), {"state": state, "model": model})
        try:
            self._server = _Server((HOST, port), handler)
        except OSError as exc:
            raise InputError(
                f"--live-port {port}: cannot serve on {HOST}:{port} ({exc.strerror}); "
                "choose another port, or 0 for any free one"
            ) from None
        self._thread = threading.Thread(
            target=self._server.serve_forever, kwargs={"poll_interval": 0.2}, daemon=True
        )

    @property
    def url(self) -> str:
        host, port = self._server.server_address[:2]
        return f"http://{host}:{port}/"

    def start(self) -> LiveServer:
        self._thread.start()
        return self

    def close(self) -> None:
        self._server.shutdown()
        self._server.server_close()
