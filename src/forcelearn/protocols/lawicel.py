"""The LAWICEL (slcan) ASCII protocol, pure: lines in, commands out; frames in, lines out.

A host talks to an slcan USB-CAN adapter over a serial port in lines of
printable ASCII ended by CR (byte 13). The adapter answers CR for success and
BEL (byte 7) for an error, and sends every received CAN frame as a line of
the same form the host uses to transmit one.

================  ======================  =====================================
host sends        meaning                 adapter answers
================  ======================  =====================================
``S0`` .. ``S8``  bitrate 10k .. 1 Mbit/s  CR (channel closed), else BEL
``S9``            83.3 kbit/s (python-can) CR / BEL as above
``sXXYY``         SJA1000 BTR0, BTR1       CR / BEL as above
``O`` / ``L``     open / open listen-only  CR, BEL if already open
``C``             close the channel        CR
``tIIIL<data>``   11-bit data frame        ``z`` CR (channel open), else BEL
``TIIIIIIIIL..``  29-bit data frame        ``Z`` CR (channel open), else BEL
``rIIIL``         11-bit remote frame      ``z`` CR
``RIIIIIIIIL``    29-bit remote frame      ``Z`` CR
``V``             version                  ``VHHSS`` CR (hardware, software)
``N``             serial number            ``NXXXX`` CR
``F``             status flags             ``FXX`` CR (hex bits, cleared on read)
``Z0`` / ``Z1``   timestamps off / on      CR (channel closed), else BEL
================  ======================  =====================================

``I`` are hex digits of the identifier, ``L`` the data length 0..8 and
``<data>`` two hex digits per byte. With timestamps on, the adapter appends
four hex digits (milliseconds, wrapping at 60000) to every frame it sends.

:func:`parse_line` turns one line (without its CR) into a command or an
:class:`Invalid` with the reason; :func:`encode_command` is its inverse and
:func:`encode_frame` writes a frame line. :class:`LineSplitter` cuts a byte
stream into lines and never grows beyond :data:`MAX_LINE` bytes, whatever it
is fed. Nothing here does I/O.
"""

from __future__ import annotations

import string
from dataclasses import dataclass

CR = b"\r"
BEL = b"\a"
MAX_LINE = 32
"""Longest valid line without its CR: ``T`` + 8 + 1 + 16 hex digits + 4 of timestamp."""
TIMESTAMP_WRAP_MS = 60_000

BITRATES: dict[int, int] = {
    0: 10_000,
    1: 20_000,
    2: 50_000,
    3: 100_000,
    4: 125_000,
    5: 250_000,
    6: 500_000,
    7: 750_000,
    8: 1_000_000,
    9: 83_300,
}
"""``S<n>`` code -> bitrate (bit/s); ``S9`` is the 83.3 kbit/s python-can uses."""

_HEX = frozenset(string.hexdigits.encode())


@dataclass(frozen=True)
class CanFrame:
    """A classic CAN frame as LAWICEL carries it (no CAN FD).

    ``data`` is empty for a remote frame, whose requested length is ``dlc``.
    """

    arbitration_id: int
    data: bytes = b""
    extended: bool = False
    remote: bool = False
    dlc: int | None = None

    def __post_init__(self) -> None:
        limit = 0x1FFFFFFF if self.extended else 0x7FF
        if not 0 <= self.arbitration_id <= limit:
            raise ValueError(f"identifier {self.arbitration_id:#x} exceeds {limit:#x}")
        if len(self.data) > 8 or (self.remote and self.data):
            raise ValueError("data: at most 8 bytes, none in a remote frame")
        dlc = len(self.data) if self.dlc is None else self.dlc
        if not 0 <= dlc <= 8 or (not self.remote and dlc != len(self.data)):
            raise ValueError(f"dlc={dlc} must be 0..8 and equal the data length")
        object.__setattr__(self, "dlc", dlc)


@dataclass(frozen=True)
class Open:
    """``O`` (or ``L`` when ``listen_only``): open the CAN channel."""

    listen_only: bool = False


@dataclass(frozen=True)
class Close:
    """``C``: close the CAN channel."""


@dataclass(frozen=True)
class SetBitrate:
    """``S<n>``: one of the standard bitrates (bit/s)."""

    bitrate: int


@dataclass(frozen=True)
class SetBtr:
    """``sXXYY``: bit timing as the SJA1000's BTR0 and BTR1 registers."""

    btr0: int
    btr1: int


@dataclass(frozen=True)
class Version:
    """``V``: hardware and software version."""


@dataclass(frozen=True)
class SerialNumber:
    """``N``: the adapter's serial number."""


@dataclass(frozen=True)
class StatusFlags:
    """``F``: read (and clear) the status flags."""


@dataclass(frozen=True)
class Timestamps:
    """``Z0`` / ``Z1``: timestamps on received frames off / on."""

    on: bool


@dataclass(frozen=True)
class Transmit:
    """``t``/``T``/``r``/``R``: send ``frame`` on the bus."""

    frame: CanFrame


@dataclass(frozen=True)
class Empty:
    """A bare CR: hosts send a few to flush a half-typed command; nothing to do."""


@dataclass(frozen=True)
class Invalid:
    """A line the adapter rejects (answered with BEL); ``reason`` says why."""

    line: bytes
    reason: str


Command = (
    Open | Close | SetBitrate | SetBtr | Version | SerialNumber | StatusFlags | Timestamps
    | Transmit | Empty
)

_SIMPLE: dict[bytes, Command] = {
    b"O": Open(),
    b"L": Open(listen_only=True),
    b"C": Close(),
    b"V": Version(),
    b"N": SerialNumber(),
    b"F": StatusFlags(),
    b"Z0": Timestamps(on=False),
    b"Z1": Timestamps(on=True),
}
_FRAME_KINDS: dict[int, tuple[bool, bool]] = {  # letter -> (extended, remote)
    ord("t"): (False, False),
    ord("T"): (True, False),
    ord("r"): (False, True),
    ord("R"): (True, True),
}


def _is_hex(chunk: bytes) -> bool:
    return bool(chunk) and all(c in _HEX for c in chunk)


def parse_frame(line: bytes, *, allow_timestamp: bool = False) -> CanFrame | Invalid:
    """Parse a ``t``/``T``/``r``/``R`` line; ``allow_timestamp`` accepts 4 trailing hex digits."""
    kind = _FRAME_KINDS.get(line[0]) if line else None
    if kind is None:
        return Invalid(line, "not a frame line")
    extended, remote = kind
    id_end = 9 if extended else 4
    ident, dlc_char = line[1:id_end], line[id_end : id_end + 1]
    if len(ident) != id_end - 1 or not _is_hex(ident):
        return Invalid(line, f"identifier needs {id_end - 1} hex digits")
    if dlc_char not in b"012345678" or not dlc_char:
        return Invalid(line, "data length must be one digit 0..8")
    dlc = int(dlc_char)
    payload = line[id_end + 1 :]
    data_digits = 0 if remote else 2 * dlc
    if len(payload) not in (data_digits, data_digits + 4) or (
        len(payload) == data_digits + 4 and not allow_timestamp
    ):
        return Invalid(line, f"expected {data_digits} hex digits of data")
    if payload and not _is_hex(payload):
        return Invalid(line, "data must be hex digits")
    try:
        return CanFrame(
            int(ident, 16), bytes.fromhex(payload[:data_digits].decode()), extended, remote, dlc
        )
    except ValueError as exc:  # identifier out of range for its kind
        return Invalid(line, str(exc))


def parse_line(line: bytes) -> Command | Invalid:
    """Parse one host line (without its CR) into a command, or :class:`Invalid`."""
    if not line:
        return Empty()
    if len(line) > MAX_LINE:
        return Invalid(line[:MAX_LINE], f"line longer than {MAX_LINE} characters")
    simple = _SIMPLE.get(line)
    if simple is not None:
        return simple
    head = line[:1]
    if head in (b"t", b"T", b"r", b"R"):
        frame = parse_frame(line)
        return frame if isinstance(frame, Invalid) else Transmit(frame)
    if head == b"S" and len(line) == 2 and line[1:] in b"0123456789":
        return SetBitrate(BITRATES[int(line[1:])])
    if head == b"s" and len(line) == 5 and _is_hex(line[1:]):
        return SetBtr(int(line[1:3], 16), int(line[3:5], 16))
    return Invalid(line, "unknown or unsupported command")


def encode_frame(frame: CanFrame, timestamp_ms: int | None = None) -> bytes:
    """Return the line (with CR) for ``frame``; ``timestamp_ms`` appends 4 hex digits."""
    letter = ("R" if frame.extended else "r") if frame.remote else ("T" if frame.extended else "t")
    ident = f"{frame.arbitration_id:08X}" if frame.extended else f"{frame.arbitration_id:03X}"
    text = f"{letter}{ident}{frame.dlc}{frame.data.hex().upper()}"
    if timestamp_ms is not None:
        text += f"{timestamp_ms % TIMESTAMP_WRAP_MS:04X}"
    return text.encode() + CR


def encode_command(command: Command) -> bytes:
    """Return the line (with CR) a host sends for ``command`` (the inverse of parse_line)."""
    match command:
        case Transmit(frame=frame):
            return encode_frame(frame)
        case SetBitrate(bitrate=bitrate):
            codes = {rate: code for code, rate in BITRATES.items()}
            if bitrate not in codes:
                raise ValueError(f"bitrate {bitrate} has no S<n> code; use SetBtr")
            return f"S{codes[bitrate]}".encode() + CR
        case SetBtr(btr0=btr0, btr1=btr1):
            return f"s{btr0:02X}{btr1:02X}".encode() + CR
        case Empty():
            return CR
    for text, simple in _SIMPLE.items():
        if simple == command:
            return text + CR
    raise ValueError(f"cannot encode {command!r}")


def version_reply(hardware: int, software: int) -> bytes:
    """``VHHSS`` CR: two decimal digits each (python-can reads them as integers)."""
    if not (0 <= hardware <= 99 and 0 <= software <= 99):
        raise ValueError("versions are two decimal digits")
    return f"V{hardware:02d}{software:02d}".encode() + CR


def serial_reply(serial_number: str) -> bytes:
    """``NXXXX`` CR: four alphanumeric characters."""
    if len(serial_number) != 4 or not serial_number.isalnum() or not serial_number.isascii():
        raise ValueError("an slcan serial number is 4 ASCII letters or digits")
    return b"N" + serial_number.encode() + CR


def status_reply(flags: int) -> bytes:
    """``FXX`` CR: the status bits as two hex digits."""
    return f"F{flags & 0xFF:02X}".encode() + CR


def transmit_reply(frame: CanFrame) -> bytes:
    """``z`` CR after an 11-bit frame was queued, ``Z`` CR after a 29-bit one."""
    return (b"Z" if frame.extended else b"z") + CR


class LineSplitter:
    """Cut a byte stream into CR-ended lines, bounded in memory.

    Line feeds are dropped (terminals send CR LF). A line longer than
    :data:`MAX_LINE` is kept only up to ``MAX_LINE + 1`` bytes, so
    :func:`parse_line` rejects it, and the stream resynchronises at the next CR.
    """

    def __init__(self) -> None:
        self._buffer = bytearray()

    def feed(self, data: bytes) -> list[bytes]:
        """Add ``data``; return the complete lines in it (without CR)."""
        lines: list[bytes] = []
        for chunk_index, chunk in enumerate(data.split(CR)):
            if chunk_index:  # a CR ended the previous line
                lines.append(bytes(self._buffer))
                self._buffer.clear()
            room = MAX_LINE + 1 - len(self._buffer)
            if room > 0:
                self._buffer += chunk.replace(b"\n", b"")[:room]
        return lines

    def clear(self) -> None:
        """Forget a half-received line (e.g. when a new client connects)."""
        self._buffer.clear()
