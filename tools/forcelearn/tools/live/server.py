"""A read-only HTTP server for the live page (standard library ``http.server``).

==================  =============================================================
``GET /``           the page (``static/index.html``)
``GET /static/*``   its CSS and JavaScript, shipped inside the package
``GET /api/state``  the model's snapshot as JSON (``?since=N``: trials from N on)
``GET /api/events`` server-sent events: a full ``state`` frame, then one frame per
                    push interval while the model changed, carrying the trials
                    since the last frame plus the present, previous, best and
                    first trials and the status
==================  =============================================================

Nothing else is served: every other method gets 405, every other path 404.
No request changes the model, the run or the robot. Each page has its own
thread that reads the model at most once per push interval: a slow page
makes fewer, larger frames (the publications folded into a frame are counted
as ``dropped_updates``); a page that stops reading for ``write_timeout_s``
is disconnected. Bound to loopback, the server also refuses requests whose
Host header names another machine (DNS rebinding).
"""

from __future__ import annotations

import ipaddress
import json
import logging
import threading
from http import HTTPStatus
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from importlib import resources
from typing import Any
from urllib.parse import parse_qs, urlsplit

from forcelearn.tools.live.model import LiveModel

log = logging.getLogger(__name__)

LOOPBACK = "127.0.0.1"
STATIC_TYPES = {
    ".html": "text/html; charset=utf-8",
    ".css": "text/css; charset=utf-8",
    ".js": "text/javascript; charset=utf-8",
}
LOCAL_HOSTS = {"127.0.0.1", "localhost", "::1", "[::1]"}


def is_loopback(host: str) -> bool:
    """True when ``host`` is a loopback address or ``localhost``."""
    if host == "localhost":
        return True
    try:
        return ipaddress.ip_address(host).is_loopback
    except ValueError:
        return False


def static_file(name: str) -> bytes | None:
    """The bytes of a file of the page (None when there is no such file)."""
    if "/" in name or name.startswith("."):
        return None
    path = resources.files("forcelearn.tools.live").joinpath("static", name)
    return path.read_bytes() if path.is_file() else None


class _Handler(BaseHTTPRequestHandler):
    server: _Server
    protocol_version = "HTTP/1.1"

    def log_message(self, format: str, *args: Any) -> None:
        log.debug("%s " + format, self.address_string(), *args)

    def do_GET(self) -> None:
        if not self._host_allowed():
            self._send(HTTPStatus.FORBIDDEN, b"host not allowed\n", "text/plain")
            return
        url = urlsplit(self.path)
        if url.path == "/":
            self._send_static("index.html")
        elif url.path.startswith("/static/"):
            self._send_static(url.path.removeprefix("/static/"))
        elif url.path == "/api/state":
            since = parse_qs(url.query).get("since", ["0"])[0]
            state = self.server.model.snapshot(int(since) if since.isdigit() else 0)
            body = json.dumps(state, separators=(",", ":")).encode()
            self._send(HTTPStatus.OK, body, "application/json")
        elif url.path == "/api/events":
            self._stream()
        else:
            self._send(HTTPStatus.NOT_FOUND, b"not found\n", "text/plain")

    def _refuse(self) -> None:
        self._send(HTTPStatus.METHOD_NOT_ALLOWED, b"read-only\n", "text/plain", allow="GET")

    do_POST = do_PUT = do_DELETE = do_PATCH = _refuse  # noqa: N815

    def _host_allowed(self) -> bool:
        if not self.server.loopback_only:
            return True
        host = urlsplit("//" + self.headers.get("Host", "")).hostname or ""
        return host in LOCAL_HOSTS or is_loopback(host)

    def _send(self, status: HTTPStatus, body: bytes, kind: str, **headers: str) -> None:
        self.send_response(status)
        self.send_header("Content-Type", kind)
        self.send_header("Content-Length", str(len(body)))
        self.send_header("Cache-Control", "no-store")
        for name, value in headers.items():
            self.send_header(name.title(), value)
        self.end_headers()
        self.wfile.write(body)

    def _send_static(self, name: str) -> None:
        body = static_file(name)
        if body is None:
            self._send(HTTPStatus.NOT_FOUND, b"not found\n", "text/plain")
            return
        kind = STATIC_TYPES.get(name[name.rfind(".") :], "application/octet-stream")
        self._send(HTTPStatus.OK, body, kind)

    def _stream(self) -> None:
        """Server-sent events until the page goes or the server closes."""
        server, model = self.server, self.server.model
        self.connection.settimeout(server.write_timeout_s)
        self.send_response(HTTPStatus.OK)
        self.send_header("Content-Type", "text/event-stream")
        self.send_header("Cache-Control", "no-store")
        self.send_header("Connection", "close")
        self.end_headers()
        self.close_connection = True
        sent_version, sent_trials, epoch = -1, 0, model.epoch
        idle = 0.0
        server.streams.add(threading.current_thread())
        try:
            while True:
                version = model.version
                if version != sent_version:
                    if model.epoch != epoch:
                        sent_trials, epoch = 0, model.epoch
                    state = model.snapshot(sent_trials)
                    if sent_version >= 0 and state["version"] - sent_version > 1:
                        model.count_dropped(state["version"] - sent_version - 1)
                    payload = json.dumps(state, separators=(",", ":"))
                    self.wfile.write(f"event: state\ndata: {payload}\n\n".encode())
                    self.wfile.flush()
                    sent_version = state["version"]
                    sent_trials = state["trials"]["since"] + len(state["trials"]["index"])
                    idle = 0.0
                elif idle >= server.heartbeat_s:
                    self.wfile.write(b": keep-alive\n\n")
                    self.wfile.flush()
                    idle = 0.0
                if server.closing.is_set():  # the last frame is out: the run has ended
                    break
                server.closing.wait(server.push_interval_s)
                idle += server.push_interval_s
        except OSError as exc:  # the page went away or stopped reading
            log.debug("live page left: %s", exc)
        finally:
            server.streams.discard(threading.current_thread())


class _Server(ThreadingHTTPServer):
    daemon_threads = True
    allow_reuse_address = True

    def __init__(
        self,
        address: tuple[str, int],
        model: LiveModel,
        push_interval_s: float,
        write_timeout_s: float,
    ):
        super().__init__(address, _Handler)
        self.model = model
        self.push_interval_s = push_interval_s
        self.write_timeout_s = write_timeout_s
        self.heartbeat_s = 15.0
        self.closing = threading.Event()
        self.streams: set[threading.Thread] = set()
        self.loopback_only = is_loopback(address[0])


class LiveServer:
    """Serves a model's page in a daemon thread; a context manager, ``close()`` twice is fine.

    Args:
        model: what the page shows.
        host: bind address; 127.0.0.1 unless the user names another.
        port: TCP port (0: any free port; :attr:`url` tells which).
        push_interval_s: the least time between two frames to one page.
        write_timeout_s: a page that takes longer to read a frame is disconnected.
    """

    def __init__(
        self,
        model: LiveModel,
        host: str = LOOPBACK,
        port: int = 0,
        push_interval_s: float = 0.25,
        write_timeout_s: float = 10.0,
    ):
        self._server = _Server((host, port), model, push_interval_s, write_timeout_s)
        self._thread = threading.Thread(
            target=self._server.serve_forever, name="live-server", daemon=True
        )
        self._thread.start()
        self._closed = False

    @property
    def url(self) -> str:
        """The page's address."""
        host, port = self._server.server_address[:2]
        name = host.decode() if isinstance(host, bytes) else str(host)
        shown = f"[{name}]" if ":" in name else name
        return f"http://{shown}:{port}/"

    def close(self) -> None:
        """Stop serving; open pages get a last frame (bounded wait), then the stream ends."""
        if self._closed:
            return
        self._closed = True
        self._server.closing.set()
        self._server.shutdown()
        self._server.server_close()
        self._thread.join()
        for stream in list(self._server.streams):  # each sends its last frame, then ends
            stream.join(timeout=self._server.write_timeout_s / 5)

    def __enter__(self) -> LiveServer:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def bind_warning(host: str) -> str | None:
    """The warning printed when the page is served beyond this machine."""
    if is_loopback(host):
        return None
    return (
        f"warning: the live page is served on {host}, reachable by anyone on that network "
        "without a password (it is read-only). Prefer the default 127.0.0.1 and an SSH "
        "tunnel: ssh -L PORT:127.0.0.1:PORT user@cell-pc (docs/live.md)"
    )
