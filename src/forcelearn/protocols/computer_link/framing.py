"""Link-layer framing of the computer link: pure, bytes in, frames out.

This module is the only place that knows the byte layout of a frame; a site
holding the real ADLP-10 specification replaces it (and ``messages``) and keeps
the driver and the emulator. See docs/computer-link.md.

Data frame (``payload`` bytes carried transparently), protocol 2.0::

    +-----+-----+--------+-----------------------+-----+-----+--------+--------+
    | DLE | STX | length | payload               | DLE | ETX | CRC lo | CRC hi |
    | 10  | 02  | 1..250 | 1..MAX_PAYLOAD bytes  | 10  | 03  |        |        |
    +-----+-----+--------+-----------------------+-----+-----+--------+--------+

Every 0x10 between STX and DLE ETX (the length byte included) is sent twice.
The length byte is the payload's size before stuffing. The CRC is
CRC-16/MODBUS (polynomial 0x8005 reflected, initial value 0xFFFF, no final
XOR) over the unstuffed length byte, payload and the ETX byte, sent low byte
first and *not* stuffed. The non-zero initial value makes leading zero bytes
change the check (with CRC-16/ARC of protocol 1.0 they did not), and the
length byte catches bytes inserted or lost inside the frame.

Link-control sequences are two bytes: DLE ACK (10 06), DLE NAK (10 15),
DLE ENQ (10 05).

:func:`decode` never raises on bad input: garbage before a frame is skipped, a
frame whose check or length fails (or that is cut short by a new DLE STX, or
that holds an illegal DLE pair, or that grows past ``MAX_PAYLOAD``) comes out as
:class:`BadFrame` so the receiver can answer DLE NAK, and decoding resumes at
the next DLE.
"""

from __future__ import annotations

import enum
from dataclasses import dataclass
from typing import NamedTuple

DLE = 0x10
STX = 0x02
ETX = 0x03
ENQ = 0x05
ACK = 0x06
NAK = 0x15

MAX_PAYLOAD = 250
"""Largest payload in bytes (before stuffing); longer frames are rejected."""


def _crc16_table() -> tuple[int, ...]:
    table = []
    for byte in range(256):
        crc = byte
        for _ in range(8):
            crc = (crc >> 1) ^ 0xA001 if crc & 1 else crc >> 1
        table.append(crc)
    return tuple(table)


_CRC_TABLE = _crc16_table()


CRC_INIT = 0xFFFF
"""Initial value of the frame check (CRC-16/MODBUS)."""


def crc16(data: bytes | bytearray | memoryview, crc: int = CRC_INIT) -> int:
    """Return the CRC-16/MODBUS of ``data`` (check value of b"123456789" is 0x4B37).

    ``crc`` continues a previous computation, so ``crc16(b, crc16(a))`` equals
    ``crc16(a + b)``.
    """
    table = _CRC_TABLE
    for byte in bytes(data):
        crc = (crc >> 8) ^ table[(crc ^ byte) & 0xFF]
    return crc


def _frame_check(body: bytes) -> int:
    """The check of a frame: the CRC over its unstuffed length byte, payload and ETX."""
    return crc16(body + b"\x03")  # = crc16(bytes((ETX,)), crc16(body))


class Control(enum.Enum):
    """A two-byte link-control sequence."""

    ACK = ACK
    NAK = NAK
    ENQ = ENQ

    @property
    def wire(self) -> bytes:
        """The bytes on the wire: DLE followed by the control byte."""
        return bytes((DLE, self.value))


@dataclass(frozen=True)
class DataFrame:
    """A data frame whose check passed; ``payload`` is the unstuffed application data."""

    payload: bytes


@dataclass(frozen=True)
class BadFrame:
    """Bytes that started a frame but failed it; answer DLE NAK. ``reason`` says why."""

    reason: str


Frame = DataFrame | Control | BadFrame


class Decoded(NamedTuple):
    """Result of :func:`decode`: drop ``consumed`` bytes, then handle ``frame`` if any.

    ``frame is None`` means more bytes are needed (``consumed`` may still be
    positive when leading garbage was skipped).
    """

    consumed: int
    frame: Frame | None


def encode(payload: bytes) -> bytes:
    """Return the wire bytes of a data frame carrying ``payload`` (1..MAX_PAYLOAD bytes)."""
    if not 0 < len(payload) <= MAX_PAYLOAD:
        raise ValueError(f"payload must be 1..{MAX_PAYLOAD} bytes, got {len(payload)}")
    body = bytes((len(payload),)) + payload
    crc = _frame_check(body)
    stuffed = body.replace(b"\x10", b"\x10\x10")
    return b"\x10\x02" + stuffed + b"\x10\x03" + crc.to_bytes(2, "little")


def encoded_size(payload: bytes) -> int:
    """``len(encode(payload))`` without building the frame, bytes.

    The overhead plus one byte per DLE in the length byte and the payload (the
    check bytes after DLE ETX are not stuffed).
    """
    return len(payload) + 7 + payload.count(DLE) + (len(payload) == DLE)


_CONTROLS = {c.value: c for c in Control}


def decode(buffer: bytes | bytearray) -> Decoded:
    """Decode the first frame in ``buffer``; see :class:`Decoded` for the result."""
    size = len(buffer)
    start = buffer.find(DLE)
    while start >= 0:
        if start + 1 >= size:
            return Decoded(start, None)
        kind = buffer[start + 1]
        if kind in _CONTROLS:
            return Decoded(start + 2, _CONTROLS[kind])
        if kind == STX:
            return _decode_data(buffer, start)
        start = buffer.find(DLE, start + 1)  # a stray DLE: not a frame start
    return Decoded(size, None)


def _decode_data(buffer: bytes | bytearray, start: int) -> Decoded:
    """Decode a data frame whose DLE STX is at ``start``."""
    size = len(buffer)
    body = bytearray()
    i = start + 2
    while i < size:
        dle = buffer.find(DLE, i)
        if dle != i:  # the bytes up to the next DLE (or the end) are data, as they stand
            end = size if dle < 0 else dle
            body += buffer[i:end]
            i = end
        elif i + 1 >= size:
            return Decoded(start, None)
        elif buffer[i + 1] == DLE:
            body.append(DLE)
            i += 2
        elif buffer[i + 1] == ETX:
            return _check(buffer, start, i + 2, bytes(body))
        elif buffer[i + 1] == STX:
            return Decoded(i, BadFrame("frame cut short by a new DLE STX"))
        else:
            return Decoded(i + 1, BadFrame(f"illegal DLE 0x{buffer[i + 1]:02X} inside a frame"))
        if len(body) > MAX_PAYLOAD + 1:  # the length byte, then the payload
            return Decoded(start + 2, BadFrame(f"frame longer than {MAX_PAYLOAD} bytes"))
    return Decoded(start, None)


def _check(buffer: bytes | bytearray, start: int, crc_at: int, body: bytes) -> Decoded:
    """Verify the CRC that follows DLE ETX at ``crc_at`` and the length byte of ``body``."""
    if crc_at + 2 > len(buffer):
        return Decoded(start, None)
    end = crc_at + 2
    if len(body) < 2:
        return Decoded(end, BadFrame("empty frame"))
    received = int.from_bytes(buffer[crc_at:end], "little")
    expected = _frame_check(body)
    if received != expected:
        return Decoded(end, BadFrame(f"CRC 0x{received:04X} != 0x{expected:04X}"))
    if body[0] != len(body) - 1:
        return Decoded(end, BadFrame(f"length byte {body[0]} but {len(body) - 1} payload bytes"))
    return Decoded(end, DataFrame(body[1:]))


class FrameReader:
    """Accumulate received bytes and hand out whole frames (pure, no I/O).

    Not thread-safe; each reader belongs to one receiving loop.
    """

    def __init__(self) -> None:
        self._buffer = bytearray()

    def feed(self, data: bytes) -> list[Frame]:
        """Add ``data`` and return every frame now complete, in order."""
        self._buffer += data
        frames: list[Frame] = []
        while self._buffer:
            consumed, frame = decode(self._buffer)
            del self._buffer[:consumed]
            if frame is None:
                break
            frames.append(frame)
        return frames

    def clear(self) -> None:
        """Forget any partial frame (after a reconnect)."""
        self._buffer.clear()

    @property
    def pending(self) -> int:
        """Bytes held back waiting for the rest of a frame."""
        return len(self._buffer)
