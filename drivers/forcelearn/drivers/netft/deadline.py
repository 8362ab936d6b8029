"""A TCP socket and an HTTP connection whose whole exchange ends by one deadline.

A socket timeout bounds each ``recv``, not the exchange: a box (or a host
posing as one) that drips a byte every half second never trips it, and a
start-up would wait forever. :class:`DeadlineSocket` sets the socket's
timeout to the time left before every ``recv``/``send``, and raises
:class:`TimeoutError` once the deadline has passed, however slowly the bytes
arrive. :class:`DeadlineHTTPConnection` is the standard library's
:class:`http.client.HTTPConnection` on such a socket (the HTTP parsing, with
its own line and header limits, stays the library's).
"""

from __future__ import annotations

import http.client
import socket
import time
from typing import Any


class DeadlineSocket(socket.socket):
    """A socket whose reads and writes fail with TimeoutError after ``deadline`` (monotonic s)."""

    deadline: float = float("inf")

    def _arm(self) -> None:
        left = self.deadline - time.monotonic()
        if left <= 0:
            raise TimeoutError("deadline passed")
        self.settimeout(left)

    def recv(self, bufsize: int, flags: int = 0) -> bytes:
        """``socket.recv`` within the deadline."""
        self._arm()
        return super().recv(bufsize, flags)

    def recv_into(self, buffer: Any, nbytes: int = 0, flags: int = 0) -> int:
        """``socket.recv_into`` within the deadline (what ``makefile`` readers call)."""
        self._arm()
        return super().recv_into(buffer, nbytes, flags)

    def send(self, data: Any, flags: int = 0) -> int:
        """``socket.send`` within the deadline."""
        self._arm()
        return super().send(data, flags)

    def sendall(self, data: Any, flags: int = 0) -> None:
        """``socket.sendall`` within the deadline."""
        self._arm()
        super().sendall(data, flags)


def connect_by(host: str, port: int, deadline: float) -> DeadlineSocket:
    """Open a TCP connection to ``host:port`` that ends by ``deadline`` (``time.monotonic``).

    Raises:
        TimeoutError: the deadline passed (connecting or later).
        OSError: the address does not resolve or every address refused.
    """
    error: OSError = OSError(f"{host!r} resolves to no address")
    for family, kind, proto, _, address in socket.getaddrinfo(host, port,
                                                              type=socket.SOCK_STREAM):
        sock = DeadlineSocket(family, kind, proto)
        sock.deadline = deadline
        try:
            left = deadline - time.monotonic()
            if left <= 0:
                raise TimeoutError("deadline passed before connecting")
            sock.settimeout(left)
            sock.connect(address)
            return sock
        except OSError as exc:
            sock.close()
            error = exc
            if isinstance(exc, TimeoutError):
                raise
    raise error


class DeadlineHTTPConnection(http.client.HTTPConnection):
    """``HTTPConnection`` whose connect, request and response all end by ``deadline``."""

    def __init__(self, host: str, port: int, deadline: float) -> None:
        super().__init__(host, port, timeout=max(deadline - time.monotonic(), 0.001))
        self.deadline = deadline

    def connect(self) -> None:
        """Open the deadline-bound socket (instead of ``socket.create_connection``)."""
        self.sock = connect_by(self.host, self.port, self.deadline)
