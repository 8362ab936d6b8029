"""The emulated Net F/T's RDT in the driver's own thread: a socket-like end, no UDP hand-over.

::

    emulator = NetFtEmulator(physics, clock, rdt_port=0, tcp_port=0)
    sensor = NetFtSensor(config, clock=..., sock=InProcessRdtSocket(emulator))

:class:`InProcessRdtSocket` is what the driver would otherwise open: an
object with the ``send``/``recv``/``settimeout``/``close`` of a connected UDP
socket (the driver's ``RdtSocket``). ``send`` hands the request's bytes to
the emulator, which handles them at once in the caller's thread
(:meth:`NetFtEmulator.take <forcelearn.emulators.netft.server.NetFtEmulator.take>`:
the same decoding, faults and sampling as a datagram off UDP); the records it
answers with are the encoded datagrams it would send, queued here, and
``recv`` returns them. What goes is the hand-over between two threads per
datagram (a Net F/T read is one request and one datagram per record), most
of an emulated Net F/T cell's wall time.

A burst's records are all queued by the time ``send`` returns, so a
blocking ``recv`` with nothing queued and no stream running raises
:class:`TimeoutError` at once where a UDP socket would wait out its timeout
for records that cannot come (the same outcome, sooner). While a stream
(sample count 0) runs, the emulator's thread paces records into the queue
in wall time and ``recv`` waits for them up to its timeout, as over UDP.
The calibration (TCP, HTTP) is still read over loopback. One client per
socket; several may be attached.
"""

from __future__ import annotations

import itertools
import threading
from collections import deque

from forcelearn.emulators.netft.server import NetFtEmulator

_clients = itertools.count(1)


class InProcessRdtSocket:
    """The driver's end of the emulated box's RDT, in process (see the module doc)."""

    def __init__(self, emulator: NetFtEmulator) -> None:
        if emulator.closed:
            raise RuntimeError("this NetFtEmulator was closed; create a new one")
        self._emulator = emulator
        self.address = ("in-process", next(_clients))
        """The address the emulator answers (no port is bound)."""
        self._inbox: deque[bytes] = deque()
        self._arrived = threading.Condition()
        self._timeout: float | None = None
        self.closed = False
        emulator.attach(self.address, self._take)

    def _take(self, datagram: bytes) -> None:
        """The emulator's "sendto" this client (any thread)."""
        with self._arrived:
            self._inbox.append(datagram)
            self._arrived.notify()

    def _require_open(self) -> NetFtEmulator:
        if self.closed:
            raise OSError("this in-process Net F/T socket is closed")
        if self._emulator.closed:
            raise OSError("the in-process Net F/T emulator was closed")
        return self._emulator

    def send(self, data: bytes, /) -> int:
        """Hand a request to the box; it is handled (and answered) before this returns."""
        self._require_open().take(bytes(data), self.address)
        return len(data)

    def recv(self, bufsize: int, /) -> bytes:
        """The next queued datagram (see the module doc for when it raises TimeoutError)."""
        emulator = self._require_open()
        inbox = self._inbox
        if not inbox:
            if self._timeout == 0.0:
                raise BlockingIOError("no datagram queued")
            if not emulator.streaming_to(self.address):
                raise TimeoutError("no datagram queued and none to come (no stream runs)")
            with self._arrived:
                if not self._arrived.wait_for(lambda: bool(inbox), self._timeout):
                    raise TimeoutError("timed out")
        data = inbox.popleft()
        return data if len(data) <= bufsize else data[:bufsize]

    def settimeout(self, value: float | None, /) -> None:
        """As a socket's: 0.0 never waits, None waits for ever (only while streaming)."""
        self._timeout = value

    def close(self) -> None:
        """Detach from the emulator (idempotent); the box keeps its state."""
        if not self.closed:
            self.closed = True
            self._emulator.detach(self.address)
