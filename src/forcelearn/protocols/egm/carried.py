"""EGM datagrams handed over in process unencoded, so neither side encodes nor parses them.

On the emulated cell the controller and the driver run in one thread and hand
each other every datagram (4 ms cycles); encoding each message and parsing it
back was a third of a cycle's work. A :class:`Carried` datagram is the message
as it was sent and the message its receiver *would* decode from its bytes;
the bytes themselves are made only when asked (``bytes(carried)``: a record,
a checkpoint, a reader that wants the wire), and are then exactly those of
``codec.encode_*`` of the sent message. The message as received is built by
:func:`as_received_robot` / :func:`as_received_sensor`, which apply what the
wire does to each value (32-bit header fields, ``float`` doubles, absent
fields), and is attached only where that is known exactly; anything else
carries nothing and is decoded from its bytes as usual. ``tests/protocols/egm``
checks that the attached message equals the decoded one.

Only the emulated lockstep route carries datagrams: over UDP (a real cell)
the bytes are the bytes, and every one is decoded and checked.

A receiver calls :func:`received_robot` / :func:`received_sensor`: the
carried message when the datagram carries one of the receiver's version,
else ``None`` (decode ``bytes(datagram)``).
"""

from __future__ import annotations

from collections.abc import Callable

from forcelearn.devices import Pose
from forcelearn.protocols.egm import codec

_MASK = 0xFFFFFFFF


class Carried:
    """A datagram not encoded yet: the message sent, and the one its receiver reads from it.

    ``bytes(datagram)`` encodes the sent message (once); ``message`` is what
    decoding those bytes gives, or None where that is not known exactly.

    An EgmRobot may leave a field to be filled in later (:attr:`pending`: the
    in-process controller's measured force, needed only of the message a wait
    ends on); :meth:`finish` fills it, and asking for the bytes finishes first.
    """

    __slots__ = ("_data", "message", "pending", "sent", "version")

    def __init__(
        self,
        sent: codec.RobotMessage | codec.SensorMessage,
        message: codec.RobotMessage | codec.SensorMessage | None,
        version: codec.Version,
    ) -> None:
        self.sent = sent
        self.message = message
        self.version: codec.Version = version
        self._data: bytes | None = None
        self.pending: Callable[[], codec.RobotMessage] | None = None
        """Gives the complete sent EgmRobot, while a field of ``sent`` is left out."""

    def finish(self) -> None:
        """Complete a message that left a field out (:attr:`pending`); no-op when complete."""
        pending = self.pending
        if pending is not None:
            sent = pending()
            self.pending = None
            self.sent = sent
            self.message = as_received_robot(sent, self.version) if _simple_robot(sent) else None

    def __bytes__(self) -> bytes:
        self.finish()
        data = self._data
        if data is None:
            sent = self.sent
            if isinstance(sent, codec.RobotMessage):
                data = codec.encode_robot(sent, self.version)
            else:
                data = codec.encode_sensor(sent, self.version)
            self._data = data
        return data

    def __len__(self) -> int:
        return len(bytes(self))


Datagram = bytes | Carried
"""What an in-process EGM endpoint hands over: wire bytes, or a datagram not encoded yet."""


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


def _received_as_is(m: codec.RobotMessage, version: codec.Version) -> bool:
    """Whether ``m`` is already what decoding its bytes gives (an emulator's usual message)."""
    force = m.measured_force
    seqno, tm_ms = m.seqno, m.tm_ms
    return (
        type(seqno) is int and 0 <= seqno <= _MASK and type(tm_ms) is int and 0 <= tm_ms <= _MASK
        and (m.feedback is None or _pose(m.feedback) is m.feedback)
        and (m.planned is None or _pose(m.planned) is m.planned)
        and type(m.joints_deg) is tuple and _floats(m.joints_deg)
        and type(m.planned_joints_deg) is tuple and _floats(m.planned_joints_deg)
        and (m.time_us is None or (type(m.time_us) is int and m.time_us >= 0))
        and (m.planned_time_us is None
             or (type(m.planned_time_us) is int and m.planned_time_us >= 0))
        and type(m.motor) is codec.MotorState and type(m.mci) is codec.MciState
        and type(m.rapid) is codec.RapidState
        and (m.convergence_met is None or type(m.convergence_met) is bool)
        and (m.utilization_pct is None or type(m.utilization_pct) is float)
        and (force is None or (type(force) is tuple and _floats(force)))
        and (m.fc_active is None if version != "rw7" or force is None
             else type(m.fc_active) is bool)
    )


def as_received_robot(m: codec.RobotMessage, version: codec.Version) -> codec.RobotMessage:
    """The message :func:`codec.decode_robot` reads from ``codec.encode_robot(m, version)``."""
    if _received_as_is(m, version):
        return m  # frozen: shared safely
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


def carry_robot(message: codec.RobotMessage, version: codec.Version) -> Carried:
    """``message`` as a ``version`` controller sends it, carrying the message as it will be read."""
    received = as_received_robot(message, version) if _simple_robot(message) else None
    return Carried(message, received, version)


def carry_sensor(message: codec.SensorMessage, version: codec.Version) -> Carried:
    """``message`` as an EgmSensor of ``version``, carrying the message as it will be read."""
    simple = (
        message.speed_ref is None
        and message.speed_ref_joints_deg_s is None
        and (message.planned is None or len(message.planned.quaternion) == 4)
    )
    return Carried(message, as_received_sensor(message) if simple else None, version)


def received_robot(data: Datagram, version: codec.Version) -> codec.RobotMessage | None:
    """The EgmRobot ``data`` carries for a ``version`` reader, or None: decode its bytes."""
    if type(data) is Carried and data.version == version:
        message = data.message
        if isinstance(message, codec.RobotMessage):
            return message
    return None


def received_sensor(data: Datagram, version: codec.Version) -> codec.SensorMessage | None:
    """The EgmSensor ``data`` carries for a ``version`` reader, or None: decode its bytes."""
    if type(data) is Carried and data.version == version:
        message = data.message
        if isinstance(message, codec.SensorMessage):
            return message
    return None
