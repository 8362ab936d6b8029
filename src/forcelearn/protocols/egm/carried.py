"""EGM datagrams that carry the message they encode, so an in-process receiver skips the parse.

On the emulated cell the controller and the driver run in one thread and hand
each other every datagram (4 ms cycles); parsing it back is a third of a
cycle's work. :class:`CarriedDatagram` is the datagram itself (``bytes``: the
same bytes go to a socket, a record or a checkpoint) with the message the
receiver *would* decode from it attached. The attached message is built by
:func:`as_received_robot` / :func:`as_received_sensor`, which apply what the
wire does to each value (32-bit header fields, ``float`` doubles, absent
fields), and is attached only where that is known exactly; anything else
carries nothing and is decoded as usual. ``tests/protocols/egm`` checks that
the attached message equals the decoded one.

A receiver calls :func:`received_robot` / :func:`received_sensor`: the
carried message when the datagram carries one of the receiver's version,
else ``None`` (decode the bytes).
"""

from __future__ import annotations

from forcelearn.devices import Pose
from forcelearn.protocols.egm import codec

_MASK = 0xFFFFFFFF


class CarriedDatagram(bytes):
    """An encoded datagram with the message its receiver would decode (see the module doc)."""

    message: codec.RobotMessage | codec.SensorMessage | None
    version: codec.Version


def _pose(pose: Pose | None) -> Pose | None:
    if pose is None:
        return None
    q = pose.quaternion
    if (type(pose) is Pose and type(pose.x_mm) is float and type(pose.y_mm) is float
            and type(pose.z_mm) is float and type(q) is tuple and _floats(q)):
        return pose  # already what the wire gives back (frozen: shared safely)
    w, x, y, z = (float(c) for c in q)
    return Pose(float(pose.x_mm), float(pose.y_mm), float(pose.z_mm), (w, x, y, z))


def _floats(values: tuple[float, ...]) -> bool:
    for v in values:  # noqa: SIM110 (a loop, not all(<genexpr>): three times per 4 ms cycle)
        if type(v) is not float:
            return False
    return True


def _tuple(values: tuple[float, ...]) -> tuple[float, ...]:
    if type(values) is tuple and _floats(values):
        return values
    return tuple(float(v) for v in values)


def _clock(time_us: int | None) -> int | None:
    return None if time_us is None else max(time_us, 0)


def _simple_robot(m: codec.RobotMessage) -> bool:
    """Whether :func:`as_received_robot` is exact for ``m`` (what the emulators send)."""
    return (
        all(t is None or (type(t) is int and t < 1 << 63) for t in (m.time_us, m.planned_time_us))
        and all(p is None or len(p.quaternion) == 4 for p in (m.feedback, m.planned))
        and (m.measured_force is None or len(m.measured_force) > 0)
    )


def as_received_robot(m: codec.RobotMessage, version: codec.Version) -> codec.RobotMessage:
    """The message :func:`codec.decode_robot` reads from ``codec.encode_robot(m, version)``."""
    force = None if m.measured_force is None else _tuple(m.measured_force)
    return codec.RobotMessage(
        seqno=m.seqno & _MASK,
        tm_ms=m.tm_ms & _MASK,
        feedback=_pose(m.feedback),
        planned=_pose(m.planned),
        joints_deg=_tuple(m.joints_deg),
        time_us=_clock(m.time_us),
        planned_joints_deg=_tuple(m.planned_joints_deg),
        planned_time_us=_clock(m.planned_time_us),
        motor=m.motor if type(m.motor) is codec.MotorState else codec.MotorState(int(m.motor)),
        mci=m.mci if type(m.mci) is codec.MciState else codec.MciState(int(m.mci)),
        rapid=m.rapid if type(m.rapid) is codec.RapidState else codec.RapidState(int(m.rapid)),
        convergence_met=None if m.convergence_met is None else bool(m.convergence_met),
        utilization_pct=None if m.utilization_pct is None else float(m.utilization_pct),
        measured_force=force,
        fc_active=bool(m.fc_active) if version == "rw7" and force is not None else None,
    )


def as_received_sensor(m: codec.SensorMessage) -> codec.SensorMessage:
    """The message :func:`codec.decode_sensor` reads from ``codec.encode_sensor(m, ...)``."""
    return codec.SensorMessage(
        seqno=m.seqno & _MASK,
        tm_ms=m.tm_ms & _MASK,
        planned=_pose(m.planned),
        planned_joints_deg=_tuple(m.planned_joints_deg),
    )


def carry_robot(message: codec.RobotMessage, version: codec.Version) -> CarriedDatagram:
    """``codec.encode_robot(message, version)``, carrying the message as it will be read."""
    datagram = CarriedDatagram(codec.encode_robot(message, version))
    datagram.version = version
    datagram.message = as_received_robot(message, version) if _simple_robot(message) else None
    return datagram


def carry_sensor(message: codec.SensorMessage, version: codec.Version) -> CarriedDatagram:
    """``codec.encode_sensor(message, version)``, carrying the message as it will be read."""
    datagram = CarriedDatagram(codec.encode_sensor(message, version))
    datagram.version = version
    simple = (
        message.speed_ref is None
        and message.speed_ref_joints_deg_s is None
        and (message.planned is None or len(message.planned.quaternion) == 4)
    )
    datagram.message = as_received_sensor(message) if simple else None
    return datagram


def received_robot(data: bytes, version: codec.Version) -> codec.RobotMessage | None:
    """The EgmRobot ``data`` carries for a ``version`` reader, or None: decode it."""
    if type(data) is CarriedDatagram and data.version == version:
        message = data.message
        if isinstance(message, codec.RobotMessage):
            return message
    return None


def received_sensor(data: bytes, version: codec.Version) -> codec.SensorMessage | None:
    """The EgmSensor ``data`` carries for a ``version`` reader, or None: decode it."""
    if type(data) is CarriedDatagram and data.version == version:
        message = data.message
        if isinstance(message, codec.SensorMessage):
            return message
    return None
