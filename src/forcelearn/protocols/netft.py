"""The ATI Net F/T wire formats, pure: RDT over UDP and READCALINFO over TCP.

Every multi-byte field is big-endian (network order). Nothing here opens a
socket; the driver and the emulator both use these functions, so they speak
the same bytes. Decoders of what the *box* sends never raise: a datagram of
the wrong size or header comes back as :class:`Rejected`, which the caller
counts. Sources: ATI Net F/T manual 9620-05 §10 (RDT); ATI's Ethernet Axia
manual 9620-05-C (the same RDT protocol: request and record semantics, quoted
in docs/netft.md); netft_utils ``netft_rdt_driver.cpp`` (READCALINFO layout),
CameronDevine/NetFT, netft/pyNetFT (command codes 0x0003 and 0x0041).

RDT request (host -> box, UDP port 49152), 8 bytes, ``>HHI``:

======  ====  ==========================================================
offset  type  field
======  ====  ==========================================================
0       u16   header, always 0x1234
2       u16   command: 0x0000 stop, 0x0002 start real-time streaming,
                0x0003 start buffered streaming, 0x0041 reset threshold
                latch, 0x0042 set software bias
4       u32   sample count: records to send, 0 = until stopped
======  ====  ==========================================================

RDT record (box -> host), 36 bytes, ``>III6i``; a real-time datagram holds
one record, a buffered one (0x0003) up to the box's RDT buffer size
(``comrdtbsiz``, 1..40) records back to back:

======  ====  ==========================================================
offset  type  field
======  ====  ==========================================================
0       u32   rdt_sequence: 1 for the first record of each request, +1 each
                record (also inside a buffered datagram)
4       u32   ft_sequence: the box's internal sample number (restarts at boot)
8       u32   status: system status code, 0 when healthy
12      i32   Fx, Fy, Fz in counts (value = counts / counts per force)
24      i32   Tx, Ty, Tz in counts (value = counts / counts per torque)
======  ====  ==========================================================

READCALINFO (TCP port 49151): request 20 bytes, command byte 0x01 then 19
zero bytes; reply 24 bytes:

======  ========  ======================================================
offset  type      field
======  ========  ======================================================
0       u16       header 0x1234
2       u8        force unit code (:data:`FORCE_UNITS`)
3       u8        torque unit code (:data:`TORQUE_UNITS`)
4       u32       counts per force unit
8       u32       counts per torque unit
12      6 x u16   scale factors (unused by forcelearn)
======  ========  ======================================================
"""

from __future__ import annotations

import enum
import struct
from dataclasses import dataclass

from forcelearn.devices import STANDARD_GRAVITY_M_S2

HEADER = 0x1234
RDT_PORT = 49152
CALIBRATION_TCP_PORT = 49151
HTTP_PORT = 80
CALIBRATION_XML_PATH = "/netftapi2.xml"
"""The box's settings page (counts per unit of the active configuration, units, RDT rate)."""
CALIBRATION_API_XML_PATH = "/netftcalapi.xml"
"""The box's calibration page (root ``netftCalibration``: ``calcpf``, ``calcpt``, units...)."""
SEQUENCE_MODULUS = 1 << 32

REQUEST = struct.Struct(">HHI")
RECORD = struct.Struct(">III6i")
CALINFO_REQUEST_SIZE = 20
CALINFO_REPLY = struct.Struct(">HBBII6H")
READCALINFO = 0x01
MAX_RECORDS_PER_DATAGRAM = 40
"""Largest RDT buffer size (``comrdtbsiz``): 40 x 36 = 1440 bytes fit one Ethernet frame."""
INT32_MIN, INT32_MAX = -(1 << 31), (1 << 31) - 1

FORCE_UNITS: dict[int, tuple[str, float]] = {
    1: ("lbf", 4.4482216152605),
    2: ("N", 1.0),
    3: ("klbf", 4448.2216152605),
    4: ("kN", 1000.0),
    5: ("kgf", STANDARD_GRAVITY_M_S2),
    6: ("gf", STANDARD_GRAVITY_M_S2 / 1000.0),
}
"""READCALINFO force unit code -> (name as netftapi2.xml ``scfgfu`` spells it, newtons per unit)."""

TORQUE_UNITS: dict[int, tuple[str, float]] = {
    1: ("lbf-in", 0.112984829027617),
    2: ("lbf-ft", 1.3558179483314),
    3: ("N-m", 1.0),
    4: ("N-mm", 0.001),
    5: ("kgf-cm", 0.0980665),
    6: ("kN-m", 1000.0),
}
"""READCALINFO torque unit code -> (name as ``scfgtu`` spells it, newton-metres per unit)."""

TORQUE_UNIT_SPELLINGS: dict[str, str] = {"Nm": "N-m", "Nmm": "N-mm", "kNm": "kN-m",
                                          "kg-cm": "kgf-cm"}
"""How a real box spells torque units on its web pages -> forcelearn's name. A live
netftapi2.xml (Gamma SI-330-30, firmware 2.2.59, quoted in a public client's tests) has
``<scfgtu>Nm</scfgtu>``; netft/pyNetFT's XML parser maps ``Nm``, ``Nmm`` and ``kg-cm`` to
``N-m``, ``N-mm``, ``kgf-cm``; ``kNm`` is the same client's table of the manual's units."""

FORCE_UNIT_SI = {name: factor for name, factor in FORCE_UNITS.values()}
_TORQUE_SI_BY_NAME = {name: factor for name, factor in TORQUE_UNITS.values()}
TORQUE_UNIT_SI = _TORQUE_SI_BY_NAME | {
    spelling: _TORQUE_SI_BY_NAME[name] for spelling, name in TORQUE_UNIT_SPELLINGS.items()}
"""Torque unit name (forcelearn's or the box's spelling) -> newton-metres per unit."""


def canonical_unit(name: str) -> str:
    """The name forcelearn uses for a unit (``"Nm"`` -> ``"N-m"``); others come back unchanged."""
    return TORQUE_UNIT_SPELLINGS.get(name, name)


def unit_codes(force_unit: str, torque_unit: str) -> tuple[int, int]:
    """The READCALINFO codes of two unit names (either spelling); unknown names raise KeyError."""
    force = {n: c for c, (n, _) in FORCE_UNITS.items()}[force_unit]
    torque = {n: c for c, (n, _) in TORQUE_UNITS.items()}[canonical_unit(torque_unit)]
    return force, torque


class Command(enum.IntEnum):
    """RDT commands (manual Table 10.1; forcelearn's driver sends stop, real-time and bias)."""

    STOP = 0x0000
    START_REALTIME = 0x0002
    START_BUFFERED = 0x0003
    """Records batched ``comrdtbsiz`` to a datagram."""
    RESET_THRESHOLD_LATCH = 0x0041
    SET_BIAS = 0x0042


@dataclass(frozen=True, slots=True)
class Request:
    """One RDT request: a command and a sample count (0 = stream until stopped)."""

    command: int
    sample_count: int = 0


@dataclass(frozen=True, slots=True)
class Record:
    """One RDT record: sequences, status word and six raw counts."""

    rdt_sequence: int
    ft_sequence: int
    status: int
    counts: tuple[int, ...]
    """Fx Fy Fz Tx Ty Tz (six)."""


@dataclass(frozen=True, slots=True)
class Rejected:
    """A datagram that is not a valid record or request, with the reason."""

    reason: str
    data: bytes


def encode_request(request: Request) -> bytes:
    """Return the 8-byte RDT request; a count outside u32 or a command outside u16 raises."""
    if not 0 <= request.command <= 0xFFFF or not 0 <= request.sample_count <= 0xFFFFFFFF:
        raise ValueError(f"request out of range: {request}")
    return REQUEST.pack(HEADER, request.command, request.sample_count)


def decode_request(data: bytes) -> Request | Rejected:
    """Decode an RDT request (the emulator's side); never raises."""
    if len(data) != REQUEST.size:
        return Rejected("REQUEST_SIZE", bytes(data))
    header, command, count = REQUEST.unpack(data)
    if header != HEADER:
        return Rejected("REQUEST_HEADER", bytes(data))
    return Request(command, count)


def encode_record(record: Record) -> bytes:
    """Return the 36-byte RDT record; counts outside int32 raise ``ValueError``."""
    return RECORD.pack(record.rdt_sequence % SEQUENCE_MODULUS,
                       record.ft_sequence % SEQUENCE_MODULUS,
                       record.status, *record.counts)


def decode_record(data: bytes) -> Record | Rejected:
    """Decode one RDT datagram (the driver's side); never raises."""
    if len(data) != RECORD.size:
        return Rejected("RECORD_SIZE", bytes(data))
    rdt, ft, status, *counts = RECORD.unpack(data)
    return Record(rdt, ft, status, tuple(counts))


def encode_datagram(records: list[Record]) -> bytes:
    """Return one RDT datagram: the records back to back (one, or a buffered batch)."""
    return b"".join(encode_record(record) for record in records)


def decode_datagram(data: bytes) -> list[Record] | Rejected:
    """Decode a datagram of 1..40 records (real-time or buffered streaming); never raises."""
    count, rest = divmod(len(data), RECORD.size)
    if rest or not 1 <= count <= MAX_RECORDS_PER_DATAGRAM:
        return Rejected("DATAGRAM_SIZE", bytes(data))
    return [Record(rdt, ft, status, tuple(counts))
            for rdt, ft, status, *counts in RECORD.iter_unpack(data)]


@dataclass(frozen=True, slots=True)
class CalInfo:
    """The READCALINFO answer: unit codes, counts per unit, scale factors."""

    force_unit_code: int
    torque_unit_code: int
    counts_per_force: int
    counts_per_torque: int
    scale_factors: tuple[int, int, int, int, int, int] = (1,) * 6


def encode_calinfo_request() -> bytes:
    """Return the 20-byte READCALINFO request."""
    return bytes([READCALINFO]) + bytes(CALINFO_REQUEST_SIZE - 1)


def is_calinfo_request(data: bytes) -> bool:
    """True if ``data`` is a READCALINFO request (the emulator's side)."""
    return len(data) == CALINFO_REQUEST_SIZE and data[0] == READCALINFO


def encode_calinfo_reply(info: CalInfo) -> bytes:
    """Return the 24-byte READCALINFO reply."""
    return CALINFO_REPLY.pack(HEADER, info.force_unit_code, info.torque_unit_code,
                              info.counts_per_force, info.counts_per_torque,
                              *info.scale_factors)


def decode_calinfo_reply(data: bytes) -> CalInfo | Rejected:
    """Decode a READCALINFO reply; never raises (the values are checked by the caller)."""
    if len(data) != CALINFO_REPLY.size:
        return Rejected("CALINFO_SIZE", bytes(data))
    header, fu, tu, cpf, cpt, *scales = CALINFO_REPLY.unpack(data)
    if header != HEADER:
        return Rejected("CALINFO_HEADER", bytes(data))
    return CalInfo(fu, tu, cpf, cpt, tuple(scales))
