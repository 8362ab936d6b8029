"""The live server against hostile clients: bad queries, idle and dripping connections, floods.

What a hostile review found: ``/api/state?since=²`` printed a traceback and sent no reply
(``"²".isdigit()`` is True, ``int("²")`` raises), and idle or half-sent connections
were held forever (150 slow clients all held).
"""

from __future__ import annotations

import json
import socket
import time
import urllib.parse
from collections.abc import Iterator

import pytest

from forcelearn.tools.live import server as live_server
from forcelearn.tools.live.model import LiveMeta, LiveModel
from forcelearn.tools.live.server import LiveServer
from forcelearn.trainer import TrialRecord

META = LiveMeta(task="surface", desired_force_n=19.6133, steps_per_trial=3, trials_target=50)
WAIT_S = 10.0
"""How long a test waits for the server to act before calling it held (the limits are < 1 s)."""


@pytest.fixture()
def live(monkeypatch: pytest.MonkeyPatch) -> Iterator[LiveServer]:
    """A server with short limits: 0.5 s idle timeout, 4 connections."""
    monkeypatch.setattr(live_server, "IDLE_TIMEOUT_S", 0.5, raising=False)
    monkeypatch.setattr(live_server, "MAX_CONNECTIONS", 4, raising=False)
    model = LiveModel(META)
    model.step(0, "generalized", {"step": 1.0, "force_n": 10.0}, 1.0)
    model.trial(TrialRecord(0, "generalized", 1, False, 0.1, 8.0, 12.0, 1.5), False, 1.0)
    with LiveServer(model, port=0, push_interval_s=0.05) as server:
        yield server


def address(server: LiveServer) -> tuple[str, int]:
    """Host and port of the server."""
    url = urllib.parse.urlsplit(server.url)
    assert url.hostname is not None and url.port is not None
    return url.hostname, url.port


def exchange(server: LiveServer, request: bytes) -> bytes:
    """Send ``request`` on a new connection; everything the server answers until it closes."""
    with socket.create_connection(address(server), timeout=WAIT_S) as sock:
        sock.sendall(request)
        answer = b""
        while chunk := sock.recv(65536):
            answer += chunk
            if b"\r\n\r\n" in answer and answer.endswith(b"\n") and b"Content-Length" in answer:
                head, _, body = answer.partition(b"\r\n\r\n")
                length = int(head.split(b"Content-Length: ")[1].split(b"\r\n")[0])
                if len(body) >= length:
                    break
        return answer


def get(server: LiveServer, target: str) -> tuple[int, bytes]:
    """Status and body of a GET of ``target`` (sent raw: no client-side quoting)."""
    answer = exchange(server, f"GET {target} HTTP/1.1\r\nHost: 127.0.0.1\r\n"
                      "Connection: close\r\n\r\n".encode())
    assert answer, f"no reply at all to GET {target}"
    head, _, body = answer.partition(b"\r\n\r\n")
    return int(head.split()[1]), body


@pytest.mark.parametrize(
    "since",
    ["²", "%C2%B2", "%D9%A1%D9%A2", "%EF%BC%91", "-1", "NaN", "inf", "1e3", "0x10", "%201",
     "99999999999999999999999", "", "1&since=2"],
)
def test_bad_since_is_a_400_with_a_one_line_reason(live: LiveServer, since: str) -> None:
    """Superscript, Arabic-Indic and full-width digits, signs, NaN, huge: 400, one line."""
    status, body = get(live, "/api/state?since=" + since)
    assert status == 400, (status, body)
    text = body.decode()
    assert text.startswith("bad request: ") and text.count("\n") == 1 and "since" in text


def test_a_good_since_still_answers(live: LiveServer) -> None:
    """The check is not a blanket refusal: since=0 and since=1 answer JSON."""
    status, body = get(live, "/api/state?since=0")
    assert status == 200 and json.loads(body)["trials"]["index"] == [0]
    status, body = get(live, "/api/state?since=1&cachebust=7")
    assert status == 200 and json.loads(body)["trials"]["index"] == []


def closed_within(sock: socket.socket, seconds: float, drip: bytes = b"") -> bool:
    """Whether the server closes ``sock`` within ``seconds`` (sending ``drip`` byte by byte)."""
    end = time.monotonic() + seconds
    sock.settimeout(0.1)
    sent = 0
    while time.monotonic() < end:
        try:
            if sent < len(drip):
                sock.sendall(drip[sent : sent + 1])
                sent += 1
            if sock.recv(4096) == b"":
                return True
        except TimeoutError:
            continue
        except OSError:  # reset by the server
            return True
    return False


def test_idle_connection_is_closed(live: LiveServer) -> None:
    """A connection that sends nothing is closed after the idle timeout."""
    with socket.create_connection(address(live)) as sock:
        assert closed_within(sock, WAIT_S)


def test_dripping_half_request_is_closed(live: LiveServer) -> None:
    """A client sending one byte every 0.1 s (each read succeeds) is closed all the same."""
    request = b"GET /api/state HTTP/1.1\r\nHost: 127.0.0.1\r\n" + b"X-Slow: " + b"a" * 200
    with socket.create_connection(address(live)) as sock:
        assert closed_within(sock, WAIT_S, drip=request)


def test_connections_over_the_cap_get_503_and_the_run_goes_on(
    live: LiveServer, monkeypatch: pytest.MonkeyPatch
) -> None:
    """With 4 kept-alive connections held, a fifth is answered 503; once they go, 200 again."""
    monkeypatch.setattr(live_server, "IDLE_TIMEOUT_S", WAIT_S, raising=False)
    with LiveServer(LiveModel(META), port=0) as server:
        held = []
        try:
            for _ in range(4):  # each answered once, so the server is serving it for sure
                sock = socket.create_connection(address(server), timeout=WAIT_S)
                held.append(sock)
                sock.sendall(b"GET /api/state HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n")
                assert sock.recv(65536).startswith(b"HTTP/1.1 200")
            status, body = get(server, "/api/state")
            assert status == 503 and b"too many connections" in body, (status, body)
        finally:
            for sock in held:
                sock.close()
        deadline = time.monotonic() + WAIT_S
        while (status := get(server, "/api/state")[0]) == 503 and time.monotonic() < deadline:
            time.sleep(0.01)
        assert status == 200


@pytest.mark.parametrize("request_line", [b"GET /api/state?since= 1 HTTP/1.1", b"\xff\xfe",
                                          b"GET /api/state HTTP/9.9", b"GET " + b"a" * 70000])
def test_malformed_request_line_is_a_one_line_400(live: LiveServer, request_line: bytes) -> None:
    """The standard library's refusals are one plain line as well, not an HTML page."""
    answer = exchange(live, request_line + b"\r\nHost: 127.0.0.1\r\n\r\n")
    if answer.startswith(b"HTTP/"):
        head, _, body = answer.partition(b"\r\n\r\n")
        status = int(head.split()[1])
    else:  # no version understood: the answer is the body alone, as HTTP/0.9 has it
        body, status = answer, int(answer.split()[0])
    assert status in (400, 414, 505) and body.count(b"\n") == 1, answer[:300]


@pytest.mark.parametrize("host", ["[::1", "[::1:8080", "[zz]", "127.0.0.1]"])
def test_a_malformed_host_is_refused_not_a_server_error(live: LiveServer, host: str) -> None:
    """Found by the live-http fuzz target: ``Host: [::1`` raised ValueError in the handler."""
    answer = exchange(live, f"GET /api/state HTTP/1.1\r\nHost: {host}\r\n"
                      "Connection: close\r\n\r\n".encode())
    assert answer.startswith(b"HTTP/1.") and int(answer.split()[1]) == 403, answer[:200]


def test_an_http_0_9_request_gets_a_status_line(live: LiveServer) -> None:
    """Found by the fuzz: HTTP/0.9 requests and early refusals had no status line."""
    for line in (b"GET /", b"GET / HTTP/0.9", b"GET GET / HTTP/0.9"):
        answer = exchange(live, line + b"\r\n\r\n")
        assert answer.startswith(b"HTTP/1.") and answer.split()[1] == b"400", answer[:200]
