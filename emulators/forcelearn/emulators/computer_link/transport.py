"""Byte transports the emulated controller listens on: a pseudo-terminal, loopback TCP, in-process.

They offer the same small interface, used by one server thread only:
``address`` (what a client passes to ``serial.serial_for_url``), ``read(timeout_s)``
(bytes, ``b""`` on timeout or while no client is connected), ``write(data)``,
``hang_up()``, ``close()``, and ``generation``, a counter that changes whenever
a connection begins or ends (the server then drops any half-received frame).

* :class:`~forcelearn.emulators.pty_endpoint.PtyEndpoint` (shared with the
  slcan adapter): the client opens ``address``, a symlink to the pty's slave side.
* :class:`TcpEndpoint`: listens on 127.0.0.1 only. One client at a time: a
  second connection while one is served is closed at once.
* :class:`InProcessEndpoint`: no thread and no descriptor; its client is a
  pyserial port opened as ``forcelearn-robot://NAME``
  (:mod:`~forcelearn.emulators.computer_link.serial_port`), whose ``write``
  hands the bytes to the controller in the caller's thread and whose ``read``
  returns the answers. One client at a time: a second open is refused.
"""

from __future__ import annotations

import contextlib
import logging
import select
import socket
from typing import Any

log = logging.getLogger(__name__)

_QUICKACK: int | None = getattr(socket, "TCP_QUICKACK", None)  # Linux only


class TcpEndpoint:
    """A TCP listener on 127.0.0.1 serving one client at a time."""

    def __init__(self, port: int = 0) -> None:
        self._listener = socket.create_server(("127.0.0.1", port))
        self._listener.setblocking(False)
        self._client: socket.socket | None = None
        self.generation = 0

    @property
    def address(self) -> str:
        """``socket://127.0.0.1:PORT`` for ``serial.serial_for_url``."""
        return f"socket://127.0.0.1:{self._listener.getsockname()[1]}"

    @property
    def connected(self) -> bool:
        """True while a client is being served."""
        return self._client is not None

    def read(self, timeout_s: float) -> bytes:
        """Accept or serve the client; return its bytes, waiting at most ``timeout_s``."""
        watch = [self._listener] + ([self._client] if self._client else [])
        ready, _, _ = select.select(watch, [], [], timeout_s)
        client = self._client
        data = self._receive(client) if client is not None and client in ready else b""
        if self._listener in ready:  # after _receive, so a client that left frees its place
            self._accept()
        return data

    def _receive(self, client: socket.socket) -> bytes:
        try:
            data = client.recv(4096)
        except (BlockingIOError, InterruptedError):
            return b""
        except OSError as exc:
            log.info("client connection failed: %s", exc)
            data = b""
        if not data:
            log.info("client disconnected")
            self.hang_up()
            return data
        if _QUICKACK is not None:
            # The driver's lone DLE ACK is followed by its next request; without an
            # immediate TCP ACK, Nagle's algorithm on the client holds that request
            # until our delayed ACK fires (~40 ms). Quick-ack mode is not sticky.
            with contextlib.suppress(OSError):
                client.setsockopt(socket.IPPROTO_TCP, _QUICKACK, 1)
        return data

    def _accept(self) -> None:
        try:
            conn, peer = self._listener.accept()
        except BlockingIOError:
            return
        if self._client is not None:
            log.warning("refused a second client %s: one client at a time", peer)
            conn.close()
            return
        conn.setblocking(True)
        conn.settimeout(1.0)
        conn.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        self._client = conn
        self.generation += 1
        log.info("client connected from %s", peer)

    def write(self, data: bytes) -> None:
        """Send ``data`` to the client, if one is connected."""
        if self._client is None:
            return
        try:
            self._client.sendall(data)
        except OSError as exc:
            log.info("client lost while sending: %s", exc)
            self.hang_up()

    def hang_up(self) -> None:
        """Close the client connection; the next client may connect."""
        if self._client is not None:
            with contextlib.suppress(OSError):
                self._client.close()
            self._client = None
            self.generation += 1

    def close(self) -> None:
        """Close the client and the listener; safe to call twice."""
        self.hang_up()
        self._listener.close()


class InProcessEndpoint:
    """The controller's end of an in-process link (``forcelearn-robot://NAME``).

    The emulator pushes the client's bytes in through its ``receive``; answers
    go to the attached client's receive buffer through :meth:`write`.
    """

    def __init__(self, name: str) -> None:
        self.name = name
        self.client: Any = None
        """The attached pyserial port (``EmulatedRobotSerial``), if any."""
        self.generation = 0

    @property
    def address(self) -> str:
        """``forcelearn-robot://NAME`` for ``serial.serial_for_url``."""
        return f"forcelearn-robot://{self.name}"

    def attach(self, client: Any) -> None:
        """Serve ``client``; raises ConnectionRefusedError while another is attached."""
        if self.client is not None and self.client is not client:
            raise ConnectionRefusedError(
                f"{self.address} is open by another client: close it first (one client at a time)"
            )
        self.client = client
        self.generation += 1

    def detach(self, client: Any) -> None:
        """The client closed its port."""
        if self.client is client:
            self.client = None
            self.generation += 1

    def read(self, timeout_s: float) -> bytes:
        """Nothing to poll: the client's writes arrive through the emulator's ``receive``."""
        return b""

    def write(self, data: bytes) -> None:
        """Deliver ``data`` to the attached client (dropped when none is attached)."""
        if self.client is not None:
            self.client.deliver(data)

    def hang_up(self) -> None:
        """Drop the connection: the client's next read or write fails as on a lost port."""
        client, self.client = self.client, None
        if client is not None:
            client.hang_up()
            self.generation += 1

    def close(self) -> None:
        """Hang up the client; safe to call twice."""
        self.hang_up()
