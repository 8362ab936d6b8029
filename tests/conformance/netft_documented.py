"""The ATI Net F/T's wire formats as ATI documents them, written out by hand.

The conformance tests build requests and read answers with these structs only,
never with forcelearn's codec (``forcelearn.protocols.netft``), so a belief the
codec and the emulator share cannot pass unseen. Sources (docs/netft.md quotes
them): ATI's Net F/T manual 9620-05 §10 and ATI's Ethernet Axia manual
9620-05-C §12 (same RDT protocol): the request is ``uint16 command_header =
0x1234; uint16 command; uint32 sample_count`` (0 = infinite), a record is
``uint32 rdt_sequence; uint32 ft_sequence; uint32 status; int32 Fx..Tz``, all
big-endian; READCALINFO is netft_utils' ``netft_rdt_driver.cpp`` layout.
"""

from __future__ import annotations

import socket
import struct
from typing import Any

from forcelearn.devices import Pose
from forcelearn.emulators.clock import SimClock
from forcelearn.emulators.netft import NetFtEmulator, NetFtModelParams
from forcelearn.emulators.physics.cell import CellPhysics
from forcelearn.emulators.physics.sponge import Sponge
from forcelearn.emulators.physics.tool import ToolParams

HEADER = 0x1234
STOP, START_REALTIME, START_BUFFERED, RESET_LATCH, SET_BIAS = 0x0000, 0x0002, 0x0003, 0x0041, 0x0042
REQUEST = struct.Struct(">HHI")
RECORD = struct.Struct(">III6i")
READCALINFO_REQUEST = bytes([0x01]) + bytes(19)
CALINFO_REPLY = struct.Struct(">HBBII6H")
INTERNAL_RATE_HZ = 7000
"""ft_sequence "increments at the internal sample rate (7000 per sec)" (both manuals)."""

QUIET = NetFtModelParams(noise_std=(0.0,) * 6, initial_bias=(0.0,) * 6,
                         bias_drift_per_sqrt_s=(0.0,) * 6)
QUIET_S = 0.3
"""How long a test listens to conclude the box sent nothing (loopback answers take < 10 ms)."""


def request(command: int, sample_count: int = 0) -> bytes:
    """An RDT request, 8 bytes, as the manual lays it out."""
    return REQUEST.pack(HEADER, command, sample_count)


def records(datagram: bytes) -> list[tuple[int, ...]]:
    """The 36-byte records of one datagram: (rdt_sequence, ft_sequence, status, Fx..Tz)."""
    assert len(datagram) % RECORD.size == 0, f"{len(datagram)} bytes is not whole records"
    return list(RECORD.iter_unpack(datagram))


def start_box(contact_mm: float = 0.0, **options: Any) -> NetFtEmulator:
    """An emulated box on free loopback ports; ``contact_mm`` presses the tool into the sponge."""
    physics = (CellPhysics(Sponge(), Pose(0.0, -contact_mm, -40.0), tool=ToolParams())
               if contact_mm else CellPhysics())
    options.setdefault("model", QUIET)
    return NetFtEmulator(physics, SimClock(), rdt_port=0, tcp_port=0, **options)


class RdtClient:
    """A bare UDP socket talking to the box's RDT port."""

    def __init__(self, box: NetFtEmulator) -> None:
        """Open the socket, connected to ``box``'s RDT port."""
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.sock.connect((box.host, box.ports["rdt_port"]))

    def __enter__(self) -> RdtClient:
        """Use as a context manager."""
        return self

    def __exit__(self, *exc: object) -> None:
        """Close the socket."""
        self.sock.close()

    def send(self, command: int, sample_count: int = 0) -> None:
        """Send one documented request."""
        self.sock.send(request(command, sample_count))

    def send_raw(self, data: bytes) -> None:
        """Send arbitrary bytes (malformed requests)."""
        self.sock.send(data)

    def datagram(self, timeout_s: float = 2.0) -> bytes | None:
        """The next datagram, or None if none comes within ``timeout_s``."""
        self.sock.settimeout(timeout_s)
        try:
            return self.sock.recv(65536)
        except TimeoutError:
            return None

    def datagrams(self, n: int) -> list[bytes]:
        """Exactly ``n`` datagrams (fails if one does not come)."""
        out: list[bytes] = []
        for _ in range(n):
            data = self.datagram()
            assert data is not None, f"only {len(out)} of {n} datagrams came"
            out.append(data)
        return out

    def drain(self) -> None:
        """Read until the box has been quiet for :data:`QUIET_S`."""
        while self.datagram(QUIET_S) is not None:
            pass
