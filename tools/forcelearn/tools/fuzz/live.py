"""Fuzz targets of the live view server, over real loopback sockets (docs/fuzzing.md).

==========  =======================================================================
target      input and check
==========  =======================================================================
live-http   one request on its own connection: a method (GET, HEAD, POST, lower
            case, garbage, huge), a path (the page, its files, the API,
            traversal variants, encoded, non-ASCII, huge), a query (odd
            ``since`` values: ``²``, Arabic-Indic, full-width, signs, NaN,
            huge; many fields), a Host header (loopback spellings, foreign
            names, none, two, non-ASCII), odd headers, sometimes byte
            mutations. The server answers a whole request with a status of
            its set (never silence, never an exception in its threads), 200
            only for a page path with a loopback Host, a 400's body is one
            line, no CORS header ever, and the connection ends in time
live-slow   batches of 1 to 150 concurrent slow clients (silent, dripping a byte
            every 50 ms, half a request, 50 requests whose answers are not read
            for 1.5 s): every
            one is closed by the server within its idle timeout (+ 3 s), at
            most ``max_connections`` are served at once (the rest get 503),
            and afterwards an ordinary GET is answered 200
==========  =======================================================================

The server runs with ``idle_timeout_s = 0.5`` so a slow client costs half a second,
not five; the property does not depend on the value.
"""

from __future__ import annotations

import random
import socket
import time
import urllib.parse
from contextlib import suppress
from importlib import resources
from typing import Any

from forcelearn.tools.fuzz.targets import FuzzFailure, Tally, apply_mutations, random_mutations

IDLE_S = 0.5
"""The server's idle timeout during the fuzz (s)."""
SLACK_S = 3.0
"""A connection still open this long after the idle timeout is a hang."""
ALLOWED = {200, 400, 403, 404, 405, 408, 414, 431, 501, 503, 505}
"""Every status the server may send."""
METHODS = ("GET", "GET", "GET", "HEAD", "POST", "PUT", "DELETE", "PATCH", "OPTIONS",
           "TRACE", "CONNECT", "get", "G\u00c9T", "BREW", "", "GET GET", "X" * 5000)
PATHS = ("/", "/api/state", "/api/events", "/static/live.js", "/static/plot.js",
         "/static/live.css", "/static/index.html", "/static/", "/static/../server.py",
         "/static/..%2fserver.py", "/static/%2e%2e/server.py", "/static/....//server.py",
         "/../../etc/passwd", "/static/..\\server.py", "//static/live.js",
         "/static/./live.js", "/static/live.js%00.png", "/static/%00", "/api/state/",
         "/api//state", "/API/STATE", "/api/state%3Fsince=1", "*", "http://evil.example/",
         "/\u00e9", "/static/\u2024\u2024/server.py", "/" + "a" * 70_000, "", "/%", "/%zz",
         "/static/.hidden", "/static/__init__.py", "/static/../../__init__.py")
SINCE = ("0", "1", "7", "\u00b2", "%C2%B2", "%D9%A1", "%EF%BC%91", "-1", "+1", "NaN", "inf",
         "1e3", "0x10", "%201", "1%20", "", "9" * 9, "9" * 10, "9" * 5000, "1.0", "%00",
         "1&since=2", "%FF", "\u0663", "\U0001d7d9")
HOSTS = ("127.0.0.1", "localhost", "[::1]", None, "evil.example", "127.0.0.1.evil.example",
         "localhost.evil.example", "127.0.0.2", "0.0.0.0", "[::ffff:127.0.0.1]", "",
         "127.0.0.1:99999", "user@evil.example", "\u00e9vil", "127.1", "2130706433",
         "[::1", "evil.example, 127.0.0.1")
LOOPBACK_HOSTS = {"127.0.0.1", "localhost", "[::1]", "127.0.0.2", "[::ffff:127.0.0.1]"}


def _static_names() -> set[str]:
    folder = resources.files("forcelearn.tools.live").joinpath("static")
    return {entry.name for entry in folder.iterdir() if entry.is_file()}


def random_request(rng: random.Random, port: int) -> tuple[bytes, dict[str, Any]]:
    """A request's bytes and what it asked (method, path, host) for the check."""
    method = rng.choice(METHODS)
    path = rng.choice(PATHS)
    if path.startswith("/api/state") and rng.random() < 0.7:
        fields = [f"since={rng.choice(SINCE)}"]
        if rng.random() < 0.1:
            fields += [f"f{i}=x" for i in range(rng.choice((3, 20)))]
        path += "?" + "&".join(fields)
    host = rng.choice(HOSTS)
    if host is not None and rng.random() < 0.5 and not host.endswith("]"):
        host = f"{host}:{port}"
    version = rng.choice(("HTTP/1.1",) * 8 + ("HTTP/1.0", "HTTP/0.9", "HTTP/2.0", "HTTP/x"))
    lines = [f"{method} {path} {version}"]
    if host is not None:
        lines.append(f"Host: {host}")
        if rng.random() < 0.03:
            lines.append("Host: evil.example")
    lines.append("Connection: close")
    roll = rng.random()
    if roll < 0.03:
        lines += [f"X-H{i}: v" for i in range(120)]
    elif roll < 0.06:
        lines.append("X-Long: " + "a" * 70_000)
    elif roll < 0.09:
        lines.append("Content-Length: 5")
    elif roll < 0.1:
        lines.append("Transfer-Encoding: chunked")
    data = ("\r\n".join(lines) + "\r\n\r\n").encode("utf-8", "surrogateescape")
    mutated = rng.random() < 0.1
    if mutated:
        data = apply_mutations(data, random_mutations(rng))
    return data, {"method": method, "path": path, "host": host, "version": version,
                  "mutated": mutated, "headers": len(lines)}


def exchange(port: int, data: bytes) -> tuple[bytes, bool, float]:
    """Send ``data``, read until the server closes; (answer, closed by the server, seconds)."""
    started = time.monotonic()
    answer = b""
    closed = False
    with socket.create_connection(("127.0.0.1", port), timeout=IDLE_S + SLACK_S) as sock:
        with suppress(OSError):
            sock.sendall(data)
            sock.shutdown(socket.SHUT_WR)  # all sent: a half-sent request ends now, not idle
        try:
            while True:
                chunk = sock.recv(65536)
                if not chunk:
                    closed = True
                    break
                answer += chunk
                if b"text/event-stream" in answer:  # the stream lives on by design
                    closed = True
                    break
        except TimeoutError:
            closed = False
        except OSError:  # reset: the server closed with unread data
            closed = True
    return answer, closed, time.monotonic() - started


def parse_answer(answer: bytes) -> tuple[int | None, dict[str, str], bytes]:
    """Status, headers (lower-case names) and body of an answer (status None: no status line)."""
    if answer.startswith(b"HTTP/"):
        head, _, body = answer.partition(b"\r\n\r\n")
        first, *rest = head.split(b"\r\n")
        parts = first.split()
        status = int(parts[1]) if len(parts) > 1 and parts[1].isdigit() else None
        headers = {}
        for line in rest:
            name, _, value = line.decode("latin1").partition(":")
            headers[name.strip().lower()] = value.strip()
        return status, headers, body
    return None, {}, answer


def page_path(path: str, static: set[str]) -> bool:
    """Whether the server may answer ``path`` (with its query) with 200."""
    if path.startswith("//"):  # the standard library's handler collapses leading slashes
        path = "/" + path.lstrip("/")
    plain = urllib.parse.urlsplit(path).path
    if plain in ("/", "/api/state", "/api/events"):
        return True
    return plain.startswith("/static/") and plain.removeprefix("/static/") in static


def loopback_host(host: str | None) -> bool:
    """Whether a Host header value names this machine."""
    if host is None:
        return False
    name = urllib.parse.urlsplit("//" + host).hostname if host else ""
    return name is not None and (f"[{name}]" in LOOPBACK_HOSTS or name in LOOPBACK_HOSTS)


def check_request(port: int, data: bytes, asked: dict[str, Any], static: set[str],
                  errors: list[str]) -> str:
    """One request: a status of the set, 200 only for a page on loopback, no CORS, in time."""
    answer, closed, seconds = exchange(port, data)
    what = f"{data[:120]!r}"
    if errors:
        raise FuzzFailure(f"the server raised {errors.pop()} on {what}")
    if not closed:
        raise FuzzFailure(f"the server raised a hang: connection open {seconds:.1f} s after "
                          f"{what}")
    status, headers, body = parse_answer(answer)
    if not answer:
        if asked["mutated"]:
            return "closed"
        raise FuzzFailure(f"the server raised no reply to a whole request {what}")
    if status not in ALLOWED:
        raise FuzzFailure(f"the server raised status {status!r} for {what}: {answer[:200]!r}")
    if any(name.startswith("access-control-") for name in headers):
        raise FuzzFailure(f"the server raised a CORS header for {what}")
    if status == 200 and not asked["mutated"] and not (
        page_path(asked["path"], static) and loopback_host(asked["host"])
        and asked["method"] in ("GET", "HEAD")
    ):
        raise FuzzFailure(f"the server raised 200 for {what}")
    lines = body.count(b"\n")
    if status == 400 and lines > 1:
        raise FuzzFailure(f"the server raised a 400 of {lines} lines for {what}")
    return str(status)


def _serve(idle_s: float = IDLE_S) -> tuple[Any, list[str]]:
    """A live server of a small model, and the list of its threads' exceptions."""
    from forcelearn.tools.live.model import LiveMeta, LiveModel
    from forcelearn.tools.live.server import LiveServer
    from forcelearn.trainer import TrialRecord

    model = LiveModel(LiveMeta(task="surface", desired_force_n=19.6, steps_per_trial=3,
                               trials_target=50))
    model.step(0, "generalized", {"step": 1.0, "force_n": 10.0}, 1.0)
    model.trial(TrialRecord(0, "generalized", 1, False, 0.1, 8.0, 12.0, 1.5), False, 1.0)
    server = LiveServer(model, port=0, push_interval_s=0.05, idle_timeout_s=idle_s)
    return server, server._server.failures  # exceptions of its threads, recorded


def _port(server: Any) -> int:
    port: int | None = urllib.parse.urlsplit(server.url).port
    assert port is not None
    return port


# ---- slow clients ---------------------------------------------------------------------
SLOW_KINDS = ("silent", "drip", "half", "unread")


def slow_batch(port: int, kinds: list[str], max_connections: int) -> list[tuple[str, float]]:
    """Open one client per behaviour at once; (behaviour, seconds until the server closed it) each.

    -1 seconds: still open at the deadline (a hang).
    """
    request = b"GET /api/events HTTP/1.1\r\nHost: 127.0.0.1\r\n" + b"X-Slow: " + b"a" * 400
    socks = []
    for behaviour in kinds:
        sock = socket.create_connection(("127.0.0.1", port), timeout=5)
        sock.setblocking(False)
        if behaviour == "half":
            sock.send(request[:30])
        elif behaviour == "unread":
            sock.send(b"GET /static/live.js HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n" * 50)
        socks.append(sock)
    started = time.monotonic()
    done: dict[int, float] = {}
    sent = [0] * len(socks)
    while len(done) < len(socks) and time.monotonic() - started < IDLE_S + SLACK_S:
        for i, (behaviour, sock) in enumerate(zip(kinds, socks, strict=True)):
            if i in done:
                continue
            try:
                if behaviour == "drip" and sent[i] < len(request):
                    sock.send(request[sent[i] : sent[i] + 1])
                    sent[i] += 1
                # "unread" reads nothing until the idle timeout has long passed (the server's
                # write must have timed out by then), then drains what was sent to see the end
                reading = behaviour != "unread" or time.monotonic() - started > IDLE_S + 1.0
                while reading:
                    chunk = sock.recv(65536)
                    if not chunk:
                        done[i] = time.monotonic() - started
                        break
            except BlockingIOError:
                pass
            except OSError:
                done[i] = time.monotonic() - started
        time.sleep(0.05)
    for sock in socks:
        sock.close()
    return [(behaviour, done.get(i, -1.0)) for i, behaviour in enumerate(kinds)]


def check_slow(behaviour: str, seconds: float) -> str:
    """A slow client must have been closed by the server in time."""
    if seconds < 0:
        raise FuzzFailure(f"the server raised a hang: a {behaviour} client was still connected "
                          f"{IDLE_S + SLACK_S:g} s after it opened (idle timeout {IDLE_S} s)")
    return "closed"


def run_target(target: str, rng: random.Random, inputs: int, tally: Tally) -> None:
    """Run ``inputs`` inputs of ``live-http`` or ``live-slow`` into ``tally``."""
    server, errors = _serve()
    try:
        port = _port(server)
        if target == "live-http":
            static = _static_names()
            for _ in range(inputs):
                data, asked = random_request(rng, port)
                tally.add(lambda d=data, a=asked:  # type: ignore[misc]
                          check_request(port, d, a, static, errors))
        elif target == "live-slow":
            remaining = inputs
            while remaining > 0:
                count = min(remaining, rng.randint(1, 150))
                kinds = [rng.choice(SLOW_KINDS) for _ in range(count)]
                results = slow_batch(port, kinds, server._server.max_connections)
                for behaviour, seconds in results:
                    tally.add(lambda k=behaviour, s=seconds: check_slow(k, s))  # type: ignore[misc]
                remaining -= count
                after = b"GET /api/state HTTP/1.1\r\nHost: 127.0.0.1\r\nConnection: close\r\n\r\n"
                deadline = time.monotonic() + SLACK_S
                status = None
                while time.monotonic() < deadline:
                    status = parse_answer(exchange(port, after)[0])[0]
                    if status == 200:
                        break
                    time.sleep(0.05)
                tally.add(lambda s=status: _after_batch(s, errors))  # type: ignore[misc]
        else:  # pragma: no cover - fuzz.py only routes this module's names here
            raise ValueError(f"unknown target {target!r}")
    finally:
        server.close()


def _after_batch(status: int | None, errors: list[str]) -> str:
    if errors:
        raise FuzzFailure(f"the server raised {errors.pop()} during a batch of slow clients")
    if status != 200:
        raise FuzzFailure(f"the server raised a hang: an ordinary GET got {status} "
                          f"{SLACK_S:g} s after a batch of slow clients ended")
    return "answered"


TARGETS = ("live-http", "live-slow")
"""The targets this module runs (registered in :mod:`forcelearn.tools.fuzz.targets`)."""
