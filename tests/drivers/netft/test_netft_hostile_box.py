"""A hostile or broken box: every failure of the calibration read is a typed SensorError.

What a hostile review found: ``setuserfilter`` nan/inf raised ValueError/OverflowError, an
unknown encoding declaration LookupError, and a server dripping one byte at a time
held the HTTP read forever whatever ``timeout_s`` said.
"""

from __future__ import annotations

import socket
import threading
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager, suppress

import pytest

from forcelearn.drivers.netft.calibration import (
    MAX_XML_BYTES,
    parse_netftapi2,
    read_calibration_http,
    read_calibration_tcp,
)
from forcelearn.errors import SensorBusError, SensorError, SensorProtocolError, SensorTimeout

GOOD = ("<netft><cfgcpf>1000000</cfgcpf><cfgcpt>1000000</cfgcpt><scfgfu>N</scfgfu>"
        "<scfgtu>N-m</scfgtu><setuserfilter>{filter}</setuserfilter></netft>")
HANG_LIMIT_S = 20.0
"""How long a read may take before the test calls it a hang (the deadline is 1 s)."""


@pytest.mark.parametrize("value", ["nan", "inf", "-inf", "1e400", "2.5", "-1", "99"])
def test_setuserfilter_that_is_no_index_is_refused_by_name(value: str) -> None:
    """A NaN raised ValueError, inf OverflowError, from ``int(float(...))``."""
    with pytest.raises(SensorProtocolError, match="setuserfilter"):
        parse_netftapi2(GOOD.format(filter=value).encode())


def test_a_plausible_filter_index_still_loads() -> None:
    """The check is not a blanket refusal: index 4 is read as 4."""
    assert parse_netftapi2(GOOD.format(filter="4").encode()).filter_index == 4


@pytest.mark.parametrize("encoding", ["foo", "x-unknown-1998", "utf-99"])
def test_unknown_encoding_declaration_is_a_protocol_error(encoding: str) -> None:
    """ElementTree raised LookupError for an encoding Python does not know."""
    body = f"<?xml version='1.0' encoding='{encoding}'?>{GOOD.format(filter=0)}".encode()
    with pytest.raises(SensorProtocolError, match="not XML"):
        parse_netftapi2(body)


@contextmanager
def box(serve: Callable[[socket.socket], None]) -> Iterator[int]:
    """A one-connection TCP server on loopback running ``serve``; yields its port."""
    listener = socket.create_server(("127.0.0.1", 0))

    def accept() -> None:
        listener.settimeout(HANG_LIMIT_S)
        try:
            conn, _ = listener.accept()
        except OSError:
            return
        with conn, suppress(OSError):
            serve(conn)

    thread = threading.Thread(target=accept, daemon=True)
    thread.start()
    try:
        yield listener.getsockname()[1]
    finally:
        listener.close()


def drip(payload: bytes, every_s: float = 0.2) -> Callable[[socket.socket], None]:
    """Send ``payload`` one byte per ``every_s`` (after the request), then hold."""
    def serve(conn: socket.socket) -> None:
        conn.recv(4096)
        for byte in payload:
            conn.sendall(bytes([byte]))
            time.sleep(every_s)
        time.sleep(HANG_LIMIT_S)
    return serve


def outcome(read: Callable[[], object]) -> BaseException | object:
    """Run ``read`` in a thread; the value or error it ended with, or a hang failure."""
    result: list[BaseException | object] = []

    def run() -> None:
        try:
            result.append(read())
        except BaseException as exc:
            result.append(exc)

    thread = threading.Thread(target=run, daemon=True)
    thread.start()
    thread.join(HANG_LIMIT_S)
    if not result:
        pytest.fail(f"the read did not end within {HANG_LIMIT_S} s with timeout_s = 1")
    return result[0]


ENDLESS_HEADERS = b"HTTP/1.1 200 OK\r\nContent-Type: text/xml\r\n" + b"X-Pad: a\r\n" * 10_000


def test_dripping_http_server_is_a_timeout_after_timeout_s() -> None:
    """One byte every 0.2 s (each recv succeeds): the read must still end after ~1 s."""
    with box(drip(ENDLESS_HEADERS)) as port:
        error = outcome(lambda: read_calibration_http("127.0.0.1", port, timeout_s=1.0))
    assert isinstance(error, SensorTimeout), error


def test_dripping_tcp_calinfo_is_a_timeout_after_timeout_s() -> None:
    """READCALINFO: 24 bytes sent one per 0.2 s with timeout_s = 1 is a timeout."""
    with box(drip(bytes(24))) as port:
        error = outcome(lambda: read_calibration_tcp("127.0.0.1", port, timeout_s=1.0))
    assert isinstance(error, SensorTimeout), error


def answer(reply: bytes, then_close: bool = True) -> Callable[[socket.socket], None]:
    """Send ``reply`` at once after the request; close, or hold the connection open."""
    def serve(conn: socket.socket) -> None:
        conn.recv(4096)
        conn.sendall(reply)
        if not then_close:
            time.sleep(HANG_LIMIT_S)
    return serve


def endless(conn: socket.socket) -> None:
    """A body with no length that never ends (until the client goes)."""
    conn.recv(4096)
    conn.sendall(b"HTTP/1.1 200 OK\r\nContent-Type: text/xml\r\n\r\n<netft>")
    while True:
        conn.sendall(b"<x>1</x>" * 8192)


@pytest.mark.parametrize(
    ("serve", "error"),
    [
        (answer(b"HTTP/1.1 200 OK\r\nContent-Length: 5000\r\n\r\n<netft/>"), SensorBusError),
        (answer(b"HTTP/1.1 200 OK\r\nContent-Length: 5000\r\n\r\n<netft/>", False),
         SensorTimeout),
        (answer(b"HTTP/1.1 200 OK\r\nContent-Length: -7\r\n\r\n<netft/>"), SensorError),
        (answer(b"HTTP/1.1 200 OK\r\nTransfer-Encoding: chunked\r\n\r\nzz\r\n"), SensorBusError),
        (answer(b"\x00\xffgarbage\r\n\r\n"), SensorBusError),
        (answer(b""), SensorBusError),
        (endless, SensorProtocolError),
    ],
    ids=["short-body", "short-body-held", "negative-length", "bad-chunk", "garbage", "silent",
         "endless-body"],
)
def test_lying_http_server_is_a_typed_error(serve: Callable[[socket.socket], None],
                                            error: type[SensorError]) -> None:
    """Wrong Content-Length, broken chunks, garbage, an endless body: each its typed error."""
    with box(serve) as port:
        got = outcome(lambda: read_calibration_http("127.0.0.1", port, timeout_s=1.0))
    assert isinstance(got, error), got
    if serve is endless:
        assert str(MAX_XML_BYTES) in str(got)
