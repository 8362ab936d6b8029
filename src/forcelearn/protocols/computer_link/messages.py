"""Application messages of the computer link: what a frame's payload means (pure).

Every payload starts with a three-byte header, little-endian::

    +------+-----------------+-------------------------------------------+
    | code | transaction (2) | body                                      |
    +------+-----------------+-------------------------------------------+

A request's ``code`` is a :class:`Command`; its reply carries ``code | 0x80``,
the same transaction number, then a status byte: 0 and the reply body, or an
:class:`ErrorCode` and a UTF-8 reason (at most ``MAX_REASON`` bytes).

=============  ====  ==============================  ====================================
command        code  request body                    reply body (status 0)
=============  ====  ==============================  ====================================
IDENTIFY       0x01  (none)                          version major u8, minor u8,
                                                     model (UTF-8)
READ_POSITION  0x02  (none)                          x y z mm, qw qx qy qz, joints 1..6
                                                     deg (13 f32)
MOVE_TO        0x03  x y z mm, qw qx qy qz (7 f32)   (none)
MOVE_BY        0x04  dx dy dz mm (3 f32)             (none)
SET_SPEED      0x05  speed mm/s (f32)                (none)
STOP           0x06  (none)                          (none)
READ_STATUS    0x07  (none)                          flags u8 (bit0 moving, bit1 in
                                                     position), last error u8,
                                                     move count u32, controller
                                                     time s (f64)
READ_TARGET    0x08  (none)                          commanded target: x y z mm,
                                                     qw qx qy qz (7 f32)
=============  ====  ==============================  ====================================

Version 2.0 added the controller's clock to READ_STATUS (so a wait for the
robot is bounded in the controller's time, identical on a real and an
emulated cell) and READ_TARGET, the target MOVE_BY adds to: the driver's
reference for relative moves and limit checks after a stop or a lost link.

Floats are IEEE-754 single precision (``f32``), so positions travel with about
0.1 µm resolution at 2 m. Swapping this module (with ``framing``) for the real
ARAP message set leaves the driver and emulator as they are, provided the new
module offers the same functions.
"""

from __future__ import annotations

import enum
import struct
from dataclasses import dataclass
from typing import Any

from forcelearn.errors import ProtocolError

PROTOCOL_VERSION = (2, 0)
"""Link protocol version: 2.0 added the frame length byte and the CRC-16/MODBUS check
(framing), the controller's clock in READ_STATUS and READ_TARGET (messages)."""
REPLY_BIT = 0x80
MAX_REASON = 200

_HEADER = struct.Struct("<BH")
_POSE = struct.Struct("<7f")
_POSITION = struct.Struct("<13f")
_INCREMENT = struct.Struct("<3f")
_SPEED = struct.Struct("<f")
_STATUS = struct.Struct("<BBId")
_OK_BYTE = b"\x00"
"""ErrorCode.OK as the reply's error byte."""


class Command(enum.IntEnum):
    """Request codes."""

    IDENTIFY = 0x01
    READ_POSITION = 0x02
    MOVE_TO = 0x03
    MOVE_BY = 0x04
    SET_SPEED = 0x05
    STOP = 0x06
    READ_STATUS = 0x07
    READ_TARGET = 0x08


class ErrorCode(enum.IntEnum):
    """Status byte of a reply; 0 is success."""

    OK = 0
    UNKNOWN_COMMAND = 1
    BAD_REQUEST = 2
    OUT_OF_WORKSPACE = 3
    JOINT_LIMIT = 4
    BAD_SPEED = 5
    BAD_ORIENTATION = 6


_COMMANDS = {int(c): c for c in Command}
"""Command by code (a dict lookup: the enum's call is several times slower, on every frame)."""

STATUS_MOVING = 0x01
STATUS_IN_POSITION = 0x02

_BODY_SIZE = {
    Command.IDENTIFY: 0,
    Command.READ_POSITION: 0,
    Command.MOVE_TO: _POSE.size,
    Command.MOVE_BY: _INCREMENT.size,
    Command.SET_SPEED: _SPEED.size,
    Command.STOP: 0,
    Command.READ_STATUS: 0,
    Command.READ_TARGET: 0,
}


@dataclass(frozen=True)
class Request:
    """A decoded request: command, transaction number and raw body."""

    command: Command
    transaction: int
    body: bytes


@dataclass(frozen=True)
class Reply:
    """A reply: ``error`` is OK or the controller's code, with ``reason``.

    ``command`` is a :class:`Command` (a raw int only when answering an unknown code).
    """

    command: Command | int
    transaction: int
    error: int
    body: bytes = b""
    reason: str = ""


@dataclass(frozen=True)
class Position:
    """READ_POSITION body: pose (mm, unit quaternion w x y z) and joint angles (deg)."""

    xyz_mm: tuple[float, float, float]
    quaternion: tuple[float, float, float, float]
    joints_deg: tuple[float, float, float, float, float, float]


@dataclass(frozen=True)
class Status:
    """READ_STATUS body."""

    moving: bool
    in_position: bool
    last_error: int
    move_count: int
    time_s: float = 0.0
    """The controller's clock, s since its power-up."""


def encode_request(command: Command, transaction: int, body: bytes = b"") -> bytes:
    """Return a request payload; ``transaction`` is 0..65535."""
    if len(body) != _BODY_SIZE[command]:
        raise ValueError(f"{command.name} body must be {_BODY_SIZE[command]} bytes")
    return _HEADER.pack(command, transaction) + body


def decode_request(payload: bytes) -> Request:
    """Parse a request payload; raises ProtocolError naming what is wrong."""
    if len(payload) < _HEADER.size:
        raise ProtocolError(f"request of {len(payload)} bytes is shorter than its header")
    code, transaction = _HEADER.unpack_from(payload)
    command = _COMMANDS.get(code)
    if command is None:
        raise ProtocolError(f"unknown command code 0x{code:02X}")
    body = payload[_HEADER.size :]
    if len(body) != _BODY_SIZE[command]:
        raise ProtocolError(f"{command.name} body is {len(body)} bytes, not {_BODY_SIZE[command]}")
    return Request(command, transaction, body)


def peek_header(payload: bytes) -> tuple[int, int] | None:
    """Return (code, transaction) of any payload, or None if it is too short."""
    if len(payload) < _HEADER.size:
        return None
    return _HEADER.unpack_from(payload)


def encode_reply(reply: Reply) -> bytes:
    """Return a reply payload (body if OK, else the reason text, cut to MAX_REASON)."""
    head = _HEADER.pack(reply.command | REPLY_BIT, reply.transaction) + bytes((reply.error,))
    if reply.error == ErrorCode.OK:
        return head + reply.body
    return head + reply.reason.encode("utf-8")[:MAX_REASON]


def encode_ok_reply(command: Command, transaction: int, body: bytes = b"") -> bytes:
    """``encode_reply(Reply(command, transaction, ErrorCode.OK, body))``, no Reply built."""
    return _HEADER.pack(command | REPLY_BIT, transaction) + _OK_BYTE + body


def status_request_transaction(payload: bytes) -> int | None:
    """The transaction number of a well-formed READ_STATUS request payload; None otherwise."""
    if len(payload) != _HEADER.size:
        return None
    code, transaction = _HEADER.unpack(payload)
    return transaction if code == Command.READ_STATUS else None


def decode_reply(payload: bytes) -> Reply:
    """Parse a reply payload; raises ProtocolError if it is not a well-formed reply."""
    if len(payload) < _HEADER.size + 1:
        raise ProtocolError(f"reply of {len(payload)} bytes is shorter than its header")
    code, transaction = _HEADER.unpack_from(payload)
    if not code & REPLY_BIT:
        raise ProtocolError(f"code 0x{code:02X} is not a reply")
    command = _COMMANDS.get(code & ~REPLY_BIT)
    if command is None:
        raise ProtocolError(f"reply to unknown command code 0x{code:02X}")
    error = payload[_HEADER.size]
    rest = payload[_HEADER.size + 1 :]
    if error != ErrorCode.OK:
        return Reply(command, transaction, error, reason=rest.decode("utf-8", "replace"))
    return Reply(command, transaction, error, body=rest)


def pose_body(xyz_mm: tuple[float, float, float], quaternion: tuple[float, ...]) -> bytes:
    """MOVE_TO body: position in mm and unit quaternion (w, x, y, z)."""
    return _POSE.pack(*xyz_mm, *quaternion)


def parse_pose(body: bytes) -> tuple[tuple[float, float, float], tuple[float, float, float, float]]:
    """Inverse of :func:`pose_body`."""
    values = _unpack(_POSE, body)
    return values[:3], values[3:]


def increment_body(delta_mm: tuple[float, float, float]) -> bytes:
    """MOVE_BY body: (dx, dy, dz) in mm."""
    return _INCREMENT.pack(*delta_mm)


def parse_increment(body: bytes) -> tuple[float, float, float]:
    """Inverse of :func:`increment_body`."""
    return _unpack(_INCREMENT, body)


def speed_body(speed_mm_s: float) -> bytes:
    """SET_SPEED body: speed in mm/s."""
    return _SPEED.pack(speed_mm_s)


def parse_speed(body: bytes) -> float:
    """Inverse of :func:`speed_body`."""
    speed_mm_s: float = _unpack(_SPEED, body)[0]
    return speed_mm_s


def position_body(position: Position) -> bytes:
    """READ_POSITION reply body."""
    return _POSITION.pack(*position.xyz_mm, *position.quaternion, *position.joints_deg)


def parse_position(body: bytes) -> Position:
    """Inverse of :func:`position_body`."""
    v = _unpack(_POSITION, body)
    return Position(v[:3], v[3:7], v[7:])


def status_body(status: Status) -> bytes:
    """READ_STATUS reply body."""
    flags = (STATUS_MOVING if status.moving else 0) | (
        STATUS_IN_POSITION if status.in_position else 0
    )
    return _STATUS.pack(flags, status.last_error, status.move_count & 0xFFFFFFFF, status.time_s)


def parse_status(body: bytes) -> Status:
    """Inverse of :func:`status_body`."""
    flags, last_error, count, time_s = _unpack(_STATUS, body)
    return Status(
        bool(flags & STATUS_MOVING), bool(flags & STATUS_IN_POSITION), last_error, count, time_s
    )


def identify_body(version: tuple[int, int], model: str) -> bytes:
    """IDENTIFY reply body: protocol version and controller model."""
    return bytes(version) + model.encode("utf-8")[:MAX_REASON]


def parse_identify(body: bytes) -> tuple[tuple[int, int], str]:
    """Inverse of :func:`identify_body`."""
    if len(body) < 2:
        raise ProtocolError("IDENTIFY reply is shorter than its version field")
    return (body[0], body[1]), body[2:].decode("utf-8", "replace")


def _unpack(layout: struct.Struct, body: bytes) -> tuple[Any, ...]:
    if len(body) != layout.size:
        raise ProtocolError(f"message body is {len(body)} bytes, expected {layout.size}")
    return layout.unpack(body)
