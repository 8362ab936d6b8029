"""EGM on the wire, written from ABB's documents alone (no forcelearn code): for conformance tests.

Field numbers and meanings: ABB application manual *Externally Guided Motion*,
RobotWare 7, 3HAC073318-001 rev K, pp. 35-38 (EgmHeader, EgmRobot, EgmSensor,
EgmPlanned, EgmFeedBack), and the ``egm.proto`` it describes (proto2; the
sub-messages as in the RobotWare 7 file: EgmJoints ``joints = 1``, EgmPose
``pos = 1, orient = 2``, EgmCartesian ``x, y, z = 1, 2, 3``, EgmQuaternion
``u0..u3 = 1..4``, EgmClock ``sec = 1, usec = 2`` "since 1970", EgmSpeedRef
``joints = 1, cartesians = 2``, EgmCartesianSpeed ``value = 1``,
EgmMeasuredForce RW7 ``fcActive = 1, force = 2``, RW6 ``force = 1``; the
state messages ``state = 1``). The protobuf wire format is Google's
(varint, 64-bit, length-delimited, 32-bit).
"""

from __future__ import annotations

import struct
from dataclasses import dataclass, field

MSGTYPE_DATA = 2
"""EgmHeader.mtype of the controller's messages (manual p.35)."""
MSGTYPE_CORRECTION = 3
"""EgmHeader.mtype the sensor sets for position guidance (manual p.35)."""
MCI_ERROR, MCI_STOPPED, MCI_RUNNING = 1, 2, 3
"""EgmMCIState values."""


def _varint(data: bytes, pos: int) -> tuple[int, int]:
    value = shift = 0
    while True:
        byte = data[pos]
        pos += 1
        value |= (byte & 0x7F) << shift
        shift += 7
        if not byte & 0x80:
            return value, pos


def fields(data: bytes) -> dict[int, list[object]]:
    """Top-level fields of one protobuf message: number -> values (int, float bits, or bytes)."""
    out: dict[int, list[object]] = {}
    pos = 0
    while pos < len(data):
        key, pos = _varint(data, pos)
        number, wire = key >> 3, key & 7
        value: object
        if wire == 0:
            value, pos = _varint(data, pos)
        elif wire == 1:
            value, pos = data[pos:pos + 8], pos + 8
        elif wire == 2:
            length, pos = _varint(data, pos)
            value, pos = data[pos:pos + length], pos + length
        elif wire == 5:
            value, pos = data[pos:pos + 4], pos + 4
        else:
            raise ValueError(f"wire type {wire}")
        out.setdefault(number, []).append((wire, value))
    return out


def doubles(entries: list[object]) -> list[float]:
    """A repeated double, packed (wire type 2) or not (wire type 1)."""
    values: list[float] = []
    for wire, raw in entries:  # type: ignore[misc]
        if wire == 1:
            values.append(struct.unpack("<d", raw)[0])
        else:
            values.extend(struct.unpack(f"<{len(raw) // 8}d", raw))
    return values


def _one(message: dict[int, list[object]], number: int) -> object | None:
    entries = message.get(number)
    return None if not entries else entries[-1][1]  # type: ignore[index]


def _sub(message: dict[int, list[object]], number: int) -> dict[int, list[object]] | None:
    raw = _one(message, number)
    return None if raw is None else fields(raw)  # type: ignore[arg-type]


def _double(message: dict[int, list[object]] | None, number: int) -> float | None:
    raw = None if message is None else _one(message, number)
    return None if raw is None else struct.unpack("<d", raw)[0]  # type: ignore[arg-type]


@dataclass
class Position:
    """EgmFeedBack or EgmPlanned as sent."""

    joints: list[float] = field(default_factory=list)
    xyz: tuple[float, float, float] | None = None
    quaternion: tuple[float, float, float, float] | None = None
    clock: tuple[int, int] | None = None
    """(sec, usec) since 1970."""


def _position(message: dict[int, list[object]] | None) -> Position:
    result = Position()
    if message is None:
        return result
    joints = _sub(message, 1)
    if joints is not None:
        result.joints = doubles(joints.get(1, []))
    pose = _sub(message, 2)
    if pose is not None:
        pos, orient = _sub(pose, 1), _sub(pose, 2)
        result.xyz = tuple(_double(pos, n) or 0.0 for n in (1, 2, 3))  # type: ignore[assignment]
        result.quaternion = tuple(  # type: ignore[assignment]
            _double(orient, n) or 0.0 for n in (1, 2, 3, 4))
    clock = _sub(message, 4)
    if clock is not None:
        result.clock = (int(_one(clock, 1) or 0), int(_one(clock, 2) or 0))  # type: ignore[call-overload]
    return result


@dataclass
class Robot:
    """The EgmRobot fields these tests read."""

    seqno: int
    mtype: int
    feedback: Position
    planned: Position
    mci: int | None
    fc_active: bool | None
    force: list[float]


def read_robot(data: bytes, rw7: bool = True) -> Robot:
    """Decode one EgmRobot datagram (RW7 or RW6 EgmMeasuredForce)."""
    top = fields(data)
    header = _sub(top, 1) or {}
    mci = _sub(top, 5)
    measured = _sub(top, 9)
    fc_active = force = None
    if measured is not None:
        if rw7:
            flag = _one(measured, 1)
            fc_active = None if flag is None else bool(flag)
            force = doubles(measured.get(2, []))
        else:
            force = doubles(measured.get(1, []))
    return Robot(
        seqno=int(_one(header, 1) or 0),  # type: ignore[call-overload]
        mtype=int(_one(header, 3) or 0),  # type: ignore[call-overload]
        feedback=_position(_sub(top, 2)),
        planned=_position(_sub(top, 3)),
        mci=None if mci is None else int(_one(mci, 1) or 0),  # type: ignore[call-overload]
        fc_active=fc_active,
        force=force or [],
    )


def _key(number: int, wire: int) -> bytes:
    return _put_varint((number << 3) | wire)


def _put_varint(value: int) -> bytes:
    out = bytearray()
    while True:
        byte = value & 0x7F
        value >>= 7
        out.append(byte | (0x80 if value else 0))
        if not value:
            return bytes(out)


def _message(number: int, body: bytes) -> bytes:
    return _key(number, 2) + _put_varint(len(body)) + body


def _doubles(number: int, values: list[float] | tuple[float, ...]) -> bytes:
    return b"".join(_key(number, 1) + struct.pack("<d", v) for v in values)


def sensor(
    seqno: int,
    xyz: tuple[float, float, float] | None = None,
    quaternion: tuple[float, float, float, float] = (0.0, 1.0, 0.0, 0.0),
    joints: list[float] | None = None,
    speed_cartesian: list[float] | None = None,
    speed_joints: list[float] | None = None,
) -> bytes:
    """One EgmSensor (mtype CORRECTION) with the given planned position and speedRef."""
    header = _key(1, 0) + _put_varint(seqno) + _key(2, 0) + _put_varint(0)
    header += _key(3, 0) + _put_varint(MSGTYPE_CORRECTION)
    planned = b""
    if joints is not None:
        planned += _message(1, _doubles(1, joints))
    if xyz is not None:
        pose = _message(1, _doubles(1, [xyz[0]]) + _doubles(2, [xyz[1]]) + _doubles(3, [xyz[2]]))
        pose += _message(2, b"".join(_doubles(n, [q]) for n, q in enumerate(quaternion, 1)))
        planned += _message(2, pose)
    speed = b""
    if speed_joints is not None:
        speed += _message(1, _doubles(1, speed_joints))
    if speed_cartesian is not None:
        speed += _message(2, _doubles(1, speed_cartesian))
    out = _message(1, header)
    if planned:
        out += _message(2, planned)
    if speed:
        out += _message(3, speed)
    return out
