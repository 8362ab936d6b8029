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

Nothing else is served: every other method gets 405, every other path 404,
a bad query value (``since`` not a trial index in ASCII digits) 400 with a
one-line reason. No request changes the model, the run or the robot.

Clients cannot hold the server: a connection that has not sent a whole
request header within :data:`IDLE_TIMEOUT_S` of opening (or of its last
answer) is closed, idle keep-alive and half-sent requests alike, however
slowly it drips bytes; at most :data:`MAX_CONNECTIONS` are open at once (the
next gets 503 and is closed). The server runs in its own threads, so the run
never waits for a client. Each page has its own
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
import re
import socket
import sys
import threading
import time
from contextlib import suppress
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
IDLE_TIMEOUT_S = 5.0
"""Longest a connection may take to send a whole request header (s), counted from its
opening or its last answer; also the longest one read or write may wait. A browser
sends its header at once; the page's event stream, once answered, is not idle."""
MAX_CONNECTIONS = 32
"""Most connections open at once; the next is answered 503 and closed. A page uses 2 to 6
(its event stream and its files), so a few pages and tabs fit."""
MAX_QUERY_FIELDS = 8
"""Most ``name=value`` fields a query may carry."""
SINCE_DIGITS = 9
"""``since`` is at most this many ASCII digits (trials 0..999,999,999)."""


class BadRequest(ValueError):
    """A request the server refuses with 400; the message is the one-line reason."""


def parse_since(query: str) -> int:
    """The ``since`` of ``/api/state``'s query (0 when absent).

    Raises:
        BadRequest: too many fields, ``since`` twice, or not 1..9 ASCII digits
            (``²``, ``-1``, ``NaN``, ``1e3``, full-width digits and a huge
            number are all refused, not guessed at).
    """
    try:
        fields = parse_qs(query, keep_blank_values=True, max_num_fields=MAX_QUERY_FIELDS)
    except ValueError:
        raise BadRequest(f"the query has more than {MAX_QUERY_FIELDS} fields") from None
    values = fields.get("since")
    if values is None:
        return 0
    if len(values) != 1:
        raise BadRequest("since is given more than once")
    if not re.fullmatch(f"[0-9]{{1,{SINCE_DIGITS}}}", values[0]):
        raise BadRequest(f"since must be a trial index, 1 to {SINCE_DIGITS} ASCII digits "
                         f"(0-9), got {values[0][:40]!r}")
    return int(values[0])


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
    # The library's own refusals (a malformed request line, headers): one plain line too.
    error_message_format = "%(code)d %(message)s\n"
    error_content_type = "text/plain; charset=utf-8"
    # Refusals before the version is known carry a status line (HTTP/0.9 would have none).
    default_request_version = "HTTP/1.0"

    def setup(self) -> None:
        super().setup()
        self.connection.settimeout(self.server.idle_timeout_s)  # each read or write, at most

    def log_message(self, format: str, *args: Any) -> None:
        log.debug("%s " + format, self.address_string(), *args)

    def handle_one_request(self) -> None:
        # The whole header must arrive by the deadline; the server's reaper closes late ones.
        self.server.watch(self.connection)
        try:
            super().handle_one_request()
        finally:
            self.server.unwatch(self.connection)

    def parse_request(self) -> bool:
        ok = super().parse_request()  # reads the headers
        self.server.unwatch(self.connection)
        if ok and (self.request_version == "HTTP/0.9" or len(self.requestline.split()) != 3):
            self.request_version = "HTTP/1.0"  # so that the refusal has a status line
            self.close_connection = True
            self.send_error(HTTPStatus.BAD_REQUEST, "the request line must be "
                            "METHOD PATH HTTP/1.x (HTTP/0.9 is not served)")
            return False
        return ok

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
            try:
                since = parse_since(url.query)
            except BadRequest as exc:
                self._send(HTTPStatus.BAD_REQUEST, f"bad request: {exc}\n".encode(),
                           "text/plain; charset=utf-8")
                return
            state = self.server.model.snapshot(since)
            body = json.dumps(state, separators=(",", ":")).encode()
            self._send(HTTPStatus.OK, body, "application/json")
        elif url.path == "/api/events":
            self._stream()
        else:
            self._send(HTTPStatus.NOT_FOUND, b"not found\n", "text/plain")

    def send_error(self, code: int, message: str | None = None,
                   explain: str | None = None) -> None:
        """The library's refusal, always with a status line (never an HTTP/0.9 bare body)."""
        if self.request_version == "HTTP/0.9":
            self.request_version = "HTTP/1.0"
        super().send_error(code, message, explain)

    def _refuse(self) -> None:
        self._send(HTTPStatus.METHOD_NOT_ALLOWED, b"read-only\n", "text/plain", allow="GET")

    do_POST = do_PUT = do_DELETE = do_PATCH = _refuse  # noqa: N815

    def _host_allowed(self) -> bool:
        if not self.server.loopback_only:
            return True
        try:
            host = urlsplit("//" + self.headers.get("Host", "")).hostname or ""
        except ValueError:  # "[::1" and the like: no host name at all
            return False
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
    request_queue_size = 64  # listen backlog: a burst of clients is accepted (or 503'd) at once

    def __init__(
        self,
        address: tuple[str, int],
        model: LiveModel,
        push_interval_s: float,
        write_timeout_s: float,
        idle_timeout_s: float = IDLE_TIMEOUT_S,
        max_connections: int = MAX_CONNECTIONS,
    ):
        super().__init__(address, _Handler)
        self.model = model
        self.push_interval_s = push_interval_s
        self.write_timeout_s = write_timeout_s
        self.idle_timeout_s = idle_timeout_s
        self.max_connections = max_connections
        self.heartbeat_s = 15.0
        self.closing = threading.Event()
        self.streams: set[threading.Thread] = set()
        self.loopback_only = is_loopback(address[0])
        self.refused = 0
        self.failures: list[str] = []
        """Exceptions (other than a client going away) that ended a request's thread."""
        self._lock = threading.Lock()
        self._open = 0
        self._deadlines: dict[socket.socket, float] = {}

    def handle_error(self, request: Any, client_address: Any) -> None:
        """A client that went away is routine (debug log); anything else is logged and kept."""
        exc = sys.exc_info()[1]
        if isinstance(exc, OSError):
            log.debug("live page client %s went away: %s", client_address, exc)
            return
        self.failures.append(f"{type(exc).__name__}: {exc}")
        log.error("the live page server failed on a request from %s", client_address,
                  exc_info=True)

    # ---- idle connections: a deadline per request header, reaped by the serving thread
    def watch(self, connection: socket.socket) -> None:
        """Close ``connection`` unless :meth:`unwatch` comes within the idle timeout."""
        with self._lock:
            self._deadlines[connection] = time.monotonic() + self.idle_timeout_s

    def unwatch(self, connection: socket.socket) -> None:
        """The connection's request header is in (or it is closing)."""
        with self._lock:
            self._deadlines.pop(connection, None)

    def service_actions(self) -> None:
        """Called by ``serve_forever`` at each poll: shut the connections past their deadline."""
        now = time.monotonic()
        with self._lock:
            late = [c for c, deadline in self._deadlines.items() if deadline <= now]
            for connection in late:
                del self._deadlines[connection]
        for connection in late:  # the handler's blocked read returns: it ends and closes
            with suppress(OSError):
                connection.shutdown(socket.SHUT_RDWR)

    # ---- the connection cap ---------------------------------------------------
    def process_request(self, request: Any, client_address: Any) -> None:
        """Serve ``request`` in its own thread, or answer 503 when the cap is reached."""
        with self._lock:
            full = self._open >= self.max_connections
            if not full:
                self._open += 1
        if full:
            self.refused += 1
            body = f"too many connections (at most {self.max_connections})\n".encode()
            head = (f"HTTP/1.1 503 Service Unavailable\r\nContent-Type: text/plain\r\n"
                    f"Content-Length: {len(body)}\r\nRetry-After: 5\r\n"
                    "Connection: close\r\n\r\n").encode()
            with suppress(OSError):
                request.setblocking(False)  # never wait for a client that does not read
                request.send(head + body)
            self.shutdown_request(request)
            return
        try:
            super().process_request(request, client_address)
        except BaseException:
            self._release()
            raise

    def process_request_thread(self, request: Any, client_address: Any) -> None:
        """The handler's thread; frees its place under the cap when it ends."""
        try:
            super().process_request_thread(request, client_address)
        finally:
            self._release()

    def _release(self) -> None:
        with self._lock:
            self._open -= 1

    @property
    def open_connections(self) -> int:
        """Connections being served now."""
        with self._lock:
            return self._open


class LiveServer:
    """Serves a model's page in a daemon thread; a context manager, ``close()`` twice is fine.

    Args:
        model: what the page shows.
        host: bind address; 127.0.0.1 unless the user names another.
        port: TCP port (0: any free port; :attr:`url` tells which).
        push_interval_s: the least time between two frames to one page.
        write_timeout_s: a page that takes longer to read a frame is disconnected.
        idle_timeout_s: a connection that sends no whole request header for this
            long is closed (None: :data:`IDLE_TIMEOUT_S`).
        max_connections: connections served at once; more get 503 (None:
            :data:`MAX_CONNECTIONS`).
    """

    def __init__(
        self,
        model: LiveModel,
        host: str = LOOPBACK,
        port: int = 0,
        push_interval_s: float = 0.25,
        write_timeout_s: float = 10.0,
        idle_timeout_s: float | None = None,
        max_connections: int | None = None,
    ):
        idle_timeout_s = IDLE_TIMEOUT_S if idle_timeout_s is None else idle_timeout_s
        max_connections = MAX_CONNECTIONS if max_connections is None else max_connections
        if not (idle_timeout_s > 0 and max_connections >= 1):
            raise ValueError(f"idle_timeout_s={idle_timeout_s} must be > 0 and "
                             f"max_connections={max_connections} >= 1")
        self._server = _Server((host, port), model, push_interval_s, write_timeout_s,
                               idle_timeout_s, max_connections)
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

    @property
    def open_connections(self) -> int:
        """Connections being served now (at most ``max_connections``)."""
        return self._server.open_connections

    @property
    def refused_connections(self) -> int:
        """Connections answered 503 because the cap was reached."""
        return self._server.refused

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
