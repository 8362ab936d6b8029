"""EGM datagrams <-> plain values, for RobotWare 6 and 7 (pure: no sockets, no clocks).

One UDP datagram holds exactly one protobuf message, so there is no framing:
``encode_*`` returns the datagram, ``decode_*`` reads one. Both directions use
the official ``protobuf`` runtime and the modules generated from ABB's
``egm.proto`` (``forcelearn.protocols.egm.proto``).

==========================  ======================  =======================================
value                       EGM field               units
==========================  ======================  =======================================
``seqno``                   header.seqno            +1 per message; 0 starts a session
``tm_ms``                   header.tm               sender's time stamp, ms (mod 2**32)
``feedback``                feedBack.cartesian      mm, quaternion (w, x, y, z) = (u0..u3)
``time_us``                 feedBack.time           µs since 1970-01-01 UTC (EgmClock sec, usec)
``planned``                 planned.cartesian       mm, quaternion
``joints_deg``              feedBack.joints         degrees, the robot's 6 axes
``planned_joints_deg``      planned.joints          degrees
``planned_time_us``         planned.time            µs since 1970: when the robot will be at
                                                    the planned position
``measured_force``          measuredForce.force     N / N·m: RW7 with ``fc_active`` false, the
                                                    raw sensor force (manual p.36)
``fc_active``               measuredForce.fcActive  RW7 only: force control active
``utilization_pct``         utilizationRate         % of the motion capacity EGM used
==========================  ======================  =======================================

An EgmSensor (:class:`SensorMessage`) carries the planned pose (pose mode),
the planned joints (joint mode) and ``speedRef``, the speed feed-forward
(cartesian mm/s and deg/s, or joint deg/s; manual 3HAC073318 p.26:
``speed = k * (pos_ref - pos) + speed_ref``).

Version evidence (:func:`detect_version`) is read from the raw wire, not from
the parsed message, because a parser built from the wrong file does not fail:
it files the other version's fields under "unknown" and reports an empty force.
"""

from __future__ import annotations

import enum
from collections.abc import Iterator
from dataclasses import dataclass
from types import ModuleType
from typing import Any, Literal

from google.protobuf.message import DecodeError

from forcelearn.devices import Pose
from forcelearn.errors import EgmVersionMismatch, ProtocolError
from forcelearn.protocols.egm.proto import egm_rw6_pb2, egm_rw7_pb2

Version = Literal["rw6", "rw7"]
VERSIONS: tuple[Version, ...] = ("rw6", "rw7")

_MODULES: dict[str, ModuleType] = {"rw6": egm_rw6_pb2, "rw7": egm_rw7_pb2}

MSGTYPE_DATA = 2
"""header.mtype of a controller's EgmRobot."""
MSGTYPE_CORRECTION = 3
"""header.mtype of a sensor's EgmSensor for position guidance."""


class MotorState(enum.IntEnum):
    """EgmMotorState.state."""

    UNDEFINED = 0
    ON = 1
    OFF = 2


class MciState(enum.IntEnum):
    """EgmMCIState.state: whether EGM is running."""

    UNDEFINED = 0
    ERROR = 1
    STOPPED = 2
    RUNNING = 3


class RapidState(enum.IntEnum):
    """EgmRapidCtrlExecState.state."""

    UNDEFINED = 0
    STOPPED = 1
    RUNNING = 2


@dataclass(frozen=True)
class RobotMessage:
    """One EgmRobot (controller to PC); ``None`` marks an absent optional field."""

    seqno: int
    tm_ms: int
    feedback: Pose | None = None
    planned: Pose | None = None
    joints_deg: tuple[float, ...] = ()
    """feedBack.joints, degrees (empty if not sent)."""
    time_us: int | None = None
    """feedBack.time: microseconds since 1970-01-01 UTC (the controller's clock)."""
    planned_joints_deg: tuple[float, ...] = ()
    """planned.joints, degrees (empty if not sent)."""
    planned_time_us: int | None = None
    """planned.time: microseconds since 1970 at which the robot will be at the planned position."""
    motor: MotorState = MotorState.UNDEFINED
    mci: MciState = MciState.UNDEFINED
    rapid: RapidState = RapidState.UNDEFINED
    convergence_met: bool | None = None
    utilization_pct: float | None = None
    measured_force: tuple[float, ...] | None = None
    fc_active: bool | None = None
    """RW7 only: EgmMeasuredForce.fcActive (force control active; false: raw sensor force)."""

    @property
    def time_s(self) -> float | None:
        """feedBack.time in seconds since 1970 (float: about 0.24 µs resolution today)."""
        return None if self.time_us is None else self.time_us / 1e6


@dataclass(frozen=True)
class SensorMessage:
    """One EgmSensor (PC to controller) for position guidance; ``None``/empty: not sent."""

    seqno: int
    tm_ms: int
    planned: Pose | None
    planned_joints_deg: tuple[float, ...] = ()
    """planned.joints, degrees (joint mode: EGMSetupUC \\Joint, EGMActJoint)."""
    speed_ref: tuple[float, ...] | None = None
    """speedRef.cartesians: x, y, z in mm/s, then rx, ry, rz in deg/s (feed-forward)."""
    speed_ref_joints_deg_s: tuple[float, ...] | None = None
    """speedRef.joints: deg/s per axis (feed-forward in joint mode)."""


def proto_module(version: str) -> ModuleType:
    """Return the generated module of ``version`` ("rw6" or "rw7")."""
    try:
        return _MODULES[version]
    except KeyError:
        raise ValueError(f"EGM version must be one of {VERSIONS}, got {version!r}") from None


# -- encoding -------------------------------------------------------------------------------


def _set_pose(target: Any, pose: Pose) -> None:
    target.pos.x, target.pos.y, target.pos.z = pose.x_mm, pose.y_mm, pose.z_mm
    q = target.orient
    q.u0, q.u1, q.u2, q.u3 = pose.quaternion


def _set_clock(clock: Any, time_us: int) -> None:
    clock.sec, clock.usec = divmod(max(time_us, 0), 1_000_000)


def _clock_us(clock: Any) -> int:
    return int(clock.sec) * 1_000_000 + int(clock.usec)


def encode_robot(message: RobotMessage, version: Version) -> bytes:
    """Return the EgmRobot datagram of ``message`` as a ``version`` controller sends it."""
    pb = proto_module(version).EgmRobot()
    pb.header.seqno = message.seqno & 0xFFFFFFFF
    pb.header.tm = message.tm_ms & 0xFFFFFFFF
    pb.header.mtype = MSGTYPE_DATA
    if message.feedback is not None:
        _set_pose(pb.feedBack.cartesian, message.feedback)
    if message.joints_deg:
        pb.feedBack.joints.joints.extend(message.joints_deg)
    if message.time_us is not None:
        _set_clock(pb.feedBack.time, message.time_us)
    if message.planned_joints_deg:
        pb.planned.joints.joints.extend(message.planned_joints_deg)
    if message.planned is not None:
        _set_pose(pb.planned.cartesian, message.planned)
    if message.planned_time_us is not None:
        _set_clock(pb.planned.time, message.planned_time_us)
    pb.motorState.state = int(message.motor)
    pb.mciState.state = int(message.mci)
    pb.rapidExecState.state = int(message.rapid)
    if message.convergence_met is not None:
        pb.mciConvergenceMet = message.convergence_met
    if message.measured_force is not None:
        if version == "rw7":
            pb.measuredForce.fcActive = bool(message.fc_active)
        pb.measuredForce.force.extend(message.measured_force)
    if message.utilization_pct is not None:
        pb.utilizationRate = message.utilization_pct
    datagram: bytes = pb.SerializeToString()
    return datagram


def encode_sensor(message: SensorMessage, version: Version) -> bytes:
    """Return the EgmSensor datagram (mtype CORRECTION) of ``message``."""
    pb = proto_module(version).EgmSensor()
    pb.header.seqno = message.seqno & 0xFFFFFFFF
    pb.header.tm = message.tm_ms & 0xFFFFFFFF
    pb.header.mtype = MSGTYPE_CORRECTION
    if message.planned_joints_deg:
        pb.planned.joints.joints.extend(message.planned_joints_deg)
    if message.planned is not None:
        _set_pose(pb.planned.cartesian, message.planned)
    if message.speed_ref_joints_deg_s is not None:
        pb.speedRef.joints.joints.extend(message.speed_ref_joints_deg_s)
    if message.speed_ref is not None:
        pb.speedRef.cartesians.value.extend(message.speed_ref)
    datagram: bytes = pb.SerializeToString()
    return datagram


# -- decoding -------------------------------------------------------------------------------


def _pose(pb_pose: Any) -> Pose | None:
    if not pb_pose.HasField("pos"):
        return None
    p, q = pb_pose.pos, pb_pose.orient
    quaternion = (q.u0, q.u1, q.u2, q.u3) if pb_pose.HasField("orient") else (1.0, 0.0, 0.0, 0.0)
    return Pose(p.x, p.y, p.z, quaternion)


def _parse(kind: str, data: bytes, version: Version) -> Any:
    pb = getattr(proto_module(version), kind)()
    try:
        pb.ParseFromString(data)
    except DecodeError as exc:
        raise ProtocolError(f"not an {kind} datagram ({len(data)} bytes): {exc}") from exc
    if not pb.HasField("header") or not pb.header.HasField("seqno"):
        raise ProtocolError(f"{kind} datagram without header.seqno ({len(data)} bytes)")
    return pb


def decode_robot(data: bytes, version: Version) -> RobotMessage:
    """Read one EgmRobot datagram with ``version``'s definition (``ProtocolError`` if broken).

    The version is not checked here; call :func:`check_version` first.
    """
    pb = _parse("EgmRobot", data, version)
    if pb.header.mtype != MSGTYPE_DATA:
        raise ProtocolError(f"EgmRobot with mtype {pb.header.mtype}, expected MSGTYPE_DATA (2)")
    fb = pb.feedBack
    force, fc_active = None, None
    if pb.HasField("measuredForce"):
        force = tuple(pb.measuredForce.force)
        if version == "rw7" and pb.measuredForce.HasField("fcActive"):
            fc_active = pb.measuredForce.fcActive
    return RobotMessage(
        seqno=pb.header.seqno,
        tm_ms=pb.header.tm,
        feedback=_pose(fb.cartesian) if fb.HasField("cartesian") else None,
        planned=_pose(pb.planned.cartesian) if pb.planned.HasField("cartesian") else None,
        joints_deg=tuple(fb.joints.joints),
        time_us=_clock_us(fb.time) if fb.HasField("time") else None,
        planned_joints_deg=tuple(pb.planned.joints.joints),
        planned_time_us=_clock_us(pb.planned.time) if pb.planned.HasField("time") else None,
        motor=MotorState(pb.motorState.state),
        mci=MciState(pb.mciState.state),
        rapid=RapidState(pb.rapidExecState.state),
        convergence_met=pb.mciConvergenceMet if pb.HasField("mciConvergenceMet") else None,
        utilization_pct=pb.utilizationRate if pb.HasField("utilizationRate") else None,
        measured_force=force,
        fc_active=fc_active,
    )


def decode_sensor(data: bytes, version: Version) -> SensorMessage:
    """Read one EgmSensor datagram (``ProtocolError`` if broken or not a correction)."""
    pb = _parse("EgmSensor", data, version)
    if pb.header.mtype != MSGTYPE_CORRECTION:
        raise ProtocolError(f"EgmSensor with mtype {pb.header.mtype}, expected CORRECTION (3)")
    planned, speed = pb.planned, pb.speedRef
    return SensorMessage(
        seqno=pb.header.seqno,
        tm_ms=pb.header.tm,
        planned=_pose(planned.cartesian) if planned.HasField("cartesian") else None,
        planned_joints_deg=tuple(planned.joints.joints),
        speed_ref=tuple(speed.cartesians.value) if speed.HasField("cartesians") else None,
        speed_ref_joints_deg_s=tuple(speed.joints.joints) if speed.HasField("joints") else None,
    )


# -- version evidence from the raw wire -----------------------------------------------------

_RW7_ONLY_ROBOT_FIELDS = frozenset({11, 12, 13, 14})
"""EgmRobot moveIndex, CollisionInfo, RAPIDfromRobot, torqueRef."""


def _varint(data: bytes, pos: int) -> tuple[int, int]:
    value = shift = 0
    while True:
        if pos >= len(data) or shift > 63:
            raise ProtocolError("truncated or overlong varint in an EGM datagram")
        byte = data[pos]
        pos += 1
        value |= (byte & 0x7F) << shift
        shift += 7
        if not byte & 0x80:
            return value, pos


def wire_fields(data: bytes) -> Iterator[tuple[int, int, bytes]]:
    """Yield (field number, wire type, raw value) of a protobuf message's top level.

    Only the wire types EGM uses (0 varint, 1 fixed64, 2 length-delimited,
    5 fixed32) are accepted; anything else is a ``ProtocolError``.
    """
    pos = 0
    while pos < len(data):
        key, pos = _varint(data, pos)
        number, wire_type = key >> 3, key & 7
        if wire_type == 0:
            start = pos
            _, pos = _varint(data, pos)
        elif wire_type in (1, 5):
            start = pos
            pos += 8 if wire_type == 1 else 4
        elif wire_type == 2:
            length, start = _varint(data, pos)
            pos = start + length
        else:
            raise ProtocolError(f"wire type {wire_type} in an EGM datagram")
        if pos > len(data) or number == 0:
            raise ProtocolError("truncated EGM datagram")
        yield number, wire_type, data[start:pos]


def _field_spans(data: bytes, pos: int, end: int) -> list[tuple[int, int, int, int]]:
    """(field number, wire type, value start, value end) of the fields in ``data[pos:end]``.

    The same reading as :func:`wire_fields` (and the same ProtocolError cases),
    without copying values: :func:`detect_version` runs on every datagram.
    """
    spans = []
    while pos < end:
        key = data[pos]
        if key < 0x80:
            pos += 1
        else:
            key, pos = _varint(data, pos)
        number, wire_type = key >> 3, key & 7
        if wire_type == 0:
            start = pos
            _, pos = _varint(data, pos)
        elif wire_type == 1 or wire_type == 5:
            start = pos
            pos += 8 if wire_type == 1 else 4
        elif wire_type == 2:
            if pos < end and data[pos] < 0x80:
                length, start = data[pos], pos + 1
            else:
                length, start = _varint(data, pos)
            pos = start + length
        else:
            raise ProtocolError(f"wire type {wire_type} in an EGM datagram")
        if pos > end or number == 0:
            raise ProtocolError("truncated EGM datagram")
        spans.append((number, wire_type, start, pos))
    return spans


def detect_version(robot_datagram: bytes) -> Version | None:
    """Return the RobotWare version an EgmRobot datagram proves, or None if it proves neither.

    RW7 evidence: EgmRobot fields 11..14, ``timeStamp`` (5) in feedBack or
    planned, ``fcActive`` (field 1 as a varint) or ``force`` as field 2 in
    measuredForce. RW6 evidence: measuredForce field 1 as doubles (fixed64 or
    packed). A controller that sends none of these is readable by either file.
    """
    data = bytes(robot_datagram)
    for number, wire_type, start, end in _field_spans(data, 0, len(data)):
        if number in _RW7_ONLY_ROBOT_FIELDS:
            return "rw7"
        in_pose_block = number in (2, 3) and wire_type == 2  # feedBack, planned
        if in_pose_block and any(n == 5 for n, _, _, _ in _field_spans(data, start, end)):
            return "rw7"
        if number == 9 and wire_type == 2:  # measuredForce
            for n, wt, _, _ in _field_spans(data, start, end):
                if n == 2 or (n == 1 and wt == 0):
                    return "rw7"
                if n == 1 and wt in (1, 2):
                    return "rw6"
    return None


def check_version(robot_datagram: bytes, version: Version) -> None:
    """Raise ``EgmVersionMismatch`` if the datagram proves another RobotWare than ``version``."""
    found = detect_version(robot_datagram)
    if found is not None and found != version:
        raise EgmVersionMismatch(
            f"the controller sends {found.upper()} egm.proto fields but robot.version = "
            f"{version!r}; set robot.version = {found!r} (a {version.upper()} parser would "
            "misread EgmMeasuredForce)"
        )
