"""A scripted server on loopback for the socket fuzz targets: it answers as told, or lies.

One listening TCP socket; each accepted connection is served in its own
daemon thread by the :class:`Script` at the head of the queue. A script is
the bytes to send and how: at once then close, at once then hold the
connection open, dripped a byte at a time, or an endless body. Used by
:mod:`.fuzz_netft` (a Net F/T's HTTP and READCALINFO servers); binds 127.0.0.1
only.
"""

from __future__ import annotations

import queue
import socket
import threading
import time
from contextlib import suppress
from dataclasses import dataclass

BEHAVIOURS = ("close", "hold", "drip", "endless")
HOLD_S = 10.0
"""Longest a script holds a connection the client does not close (the client's deadline
ends it long before)."""


@dataclass(frozen=True)
class Script:
    """What the server does with one connection.

    Attributes:
        reply: the bytes sent after the request arrives.
        behaviour: ``close`` (send, close), ``hold`` (send, keep open), ``drip``
            (one byte per ``drip_s``, then hold), ``endless`` (send, then filler forever).
        drip_s: seconds between dripped bytes.
    """

    reply: bytes
    behaviour: str = "close"
    drip_s: float = 0.05


class ScriptedServer:
    """Serves queued :class:`Script` s on 127.0.0.1 (``default`` when none is queued)."""

    def __init__(self, default: Script | None = None) -> None:
        self._default = default or Script(b"")
        self._listener = socket.create_server(("127.0.0.1", 0), backlog=64)
        self._scripts: queue.Queue[Script] = queue.Queue()
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._accept, name="fuzz-box", daemon=True)
        self._thread.start()

    @property
    def port(self) -> int:
        """The TCP port it listens on."""
        port: int = self._listener.getsockname()[1]
        return port

    def push(self, script: Script) -> None:
        """Queue the script for the next connection."""
        self._scripts.put(script)

    def _accept(self) -> None:
        self._listener.settimeout(0.1)  # closing a socket does not wake accept(): poll
        while not self._stop.is_set():
            try:
                conn, _ = self._listener.accept()
            except TimeoutError:
                continue
            except OSError:
                return
            try:
                script = self._scripts.get_nowait()
            except queue.Empty:
                script = self._default
            threading.Thread(target=self._serve, args=(conn, script), daemon=True).start()

    def _serve(self, conn: socket.socket, script: Script) -> None:
        with conn, suppress(OSError):
            conn.settimeout(HOLD_S)
            conn.recv(65536)  # the request (its content does not change the script)
            if script.behaviour == "drip":
                for byte in script.reply:
                    if self._stop.is_set():
                        return
                    conn.sendall(bytes((byte,)))
                    time.sleep(script.drip_s)
            else:
                conn.sendall(script.reply)
            if script.behaviour == "endless":
                filler = b"<x>0</x>" * 4096
                end = time.monotonic() + HOLD_S
                while time.monotonic() < end and not self._stop.is_set():
                    conn.sendall(filler)
            elif script.behaviour in ("hold", "drip"):
                conn.recv(1)  # until the client closes (or HOLD_S)

    def close(self) -> None:
        """Stop accepting; serving threads end with their connections."""
        self._stop.set()
        self._thread.join(timeout=5)
        self._listener.close()

    def __enter__(self) -> ScriptedServer:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
