"""The controller's side of the computer link: frames in, answers out (no I/O).

It reuses the driver's codec (``framing`` and ``messages``, the protocol
itself) and nothing else of the driver. Rules, as in docs/computer-link.md:

* a data frame whose check fails gets DLE NAK;
* an intact request gets DLE ACK, then its reply frame;
* a request equal to the last one executed (same transaction number and
  bytes) is a retransmission: it is ACKed and the cached reply sent again,
  it is **never executed twice**;
* DLE ENQ or DLE NAK from the PC asks for the last reply again (DLE NAK if
  there is none yet); DLE ACK needs no answer.

Time (simulated, on the cell's :class:`~forcelearn.emulators.clock.SimClock`):
a frame from the PC occupies the PC-to-controller wire for its bytes at the
line's character time, starting when the PC is ready (the clock's present
time) and the wire is free; the PC's DLE ACK of a reply starts when that
reply has arrived, and does not move the clock (the PC does not wait for it);
it is reserved on the wire with the reply, so when this thread happens to
read it changes nothing.
A request is executed when its last byte has arrived; the DLE ACK follows at
once and the reply ``reply_latency_s`` later, each taking its bytes' time on
the controller-to-PC wire. The clock then stands at the end of the answer.
"""

from __future__ import annotations

import logging
import threading
from dataclasses import dataclass
from typing import Any

from forcelearn.devices import Pose
from forcelearn.emulators.clock import Wire, serial_char_time_s
from forcelearn.emulators.physics.arm import (
    ArmConfig,
    check_target,
    joint_angles_deg,
)
from forcelearn.emulators.physics.arm_motion import ArmMotion
from forcelearn.emulators.physics.cell import CellPhysics
from forcelearn.errors import ProtocolError
from forcelearn.protocols.computer_link import framing
from forcelearn.protocols.computer_link import messages as m

log = logging.getLogger(__name__)

MODEL = "forcelearn S3 controller emulator"
VERSION = m.PROTOCOL_VERSION
"""Link protocol version this emulator speaks (reported by IDENTIFY)."""
_REFUSAL_CODE = {
    "workspace": m.ErrorCode.OUT_OF_WORKSPACE,
    "joint": m.ErrorCode.JOINT_LIMIT,
    "orientation": m.ErrorCode.BAD_ORIENTATION,
}


@dataclass(frozen=True)
class Answer:
    """Bytes to send: ``kind`` is "ack", "nak" or "reply" (so faults can pick them)."""

    kind: str
    wire: bytes
    executed: bool = False


class ControllerEngine:
    """Protocol engine and robot state of one emulated controller; thread-safe.

    Args:
        config: arm geometry, limits, motion settings and reply latency.
        physics: shared cell physics with the cell's clock; the engine gives it
            an :class:`ArmMotion` if it has none.
        char_time_s: seconds per character on the serial line (0: the wire
            costs no time).
    """

    def __init__(
        self,
        config: ArmConfig | None = None,
        physics: CellPhysics | None = None,
        char_time_s: float = serial_char_time_s(9600),
    ) -> None:
        self.config = config or ArmConfig()
        self.physics = physics or CellPhysics(pose=self.config.home)
        self.clock = self.physics.clock
        if self.physics.motion is None:
            self.physics.attach_motion(ArmMotion(self.config.motion_params(), self.config.home))
        self.motion: ArmMotion = self.physics.motion  # type: ignore[assignment]
        self.char_time_s = float(char_time_s)
        self.rx_wire = Wire(self.clock)
        """PC-to-controller direction of the serial line."""
        self.tx_wire = Wire(self.clock)
        """Controller-to-PC direction of the serial line."""
        self._lock = threading.RLock()
        self._last_request: bytes | None = None
        self._last_reply: bytes | None = None
        """The last reply's frame (None: not built yet, or no reply yet: see ``_last_payload``)."""
        self._payload: bytes | None = None
        """The last reply's payload once encoded (see :attr:`_last_payload`)."""
        self._status_reply: tuple[int, m.Status] | None = None
        """A carried READ_STATUS reply not encoded yet: (transaction, status); None: none."""
        self._last_error = 0
        self.never_in_position = False
        """Fault: READ_STATUS never reports in position (a robot that cannot settle)."""
        self.move_count = 0
        """Moves executed (accepted MOVE_TO / MOVE_BY); retransmissions never count."""

    @property
    def _last_payload(self) -> bytes | None:
        """The last reply's payload (None: no reply yet).

        A carried status's is encoded when asked (a repeat of its request or a DLE ENQ:
        polls are rarely asked again).
        """
        if self._status_reply is not None:
            tns, status = self._status_reply
            self._payload = m.encode_ok_reply(m.Command.READ_STATUS, tns, m.status_body(status))
            self._status_reply = None
        return self._payload

    @_last_payload.setter
    def _last_payload(self, payload: bytes | None) -> None:
        self._payload, self._status_reply = payload, None

    @property
    def pose(self) -> Pose:
        """The pose the robot has reached by the clock's present time."""
        with self._lock:
            self.physics.advance_to()
            return self.motion.pose

    def handle(self, frame: framing.Frame, wire_bytes: int | None = None) -> list[Answer]:
        """Return what to send in answer to one received frame; advance the clock.

        ``wire_bytes`` is the frame's length on the wire (default: its encoded length).
        """
        with self._lock:
            size = _wire_size(frame) if wire_bytes is None else wire_bytes
            if frame is framing.Control.ACK:  # the PC's ACK of a reply: reserved with the reply
                return []
            _, arrived = self.rx_wire.transmit(size * self.char_time_s)
            self.clock.advance_to(arrived)
            answers = self._answers(frame)
            self._schedule(answers, arrived)
            return answers

    def carry(self, payload: bytes) -> bytes:
        """Answer one intact request payload as :meth:`handle` answers its frame; its reply payload.

        For a client that hands over payloads, not frames (the in-process port): the
        same clock, wires, execution and retransmission rule as the frame, and the
        reply payload the frame would carry; no frame is encoded, checked or decoded
        (the nominal sizes the wires are charged do not depend on the framing). The
        DLE ACK and the PC's DLE ACK of the reply take their wire time as on the line.
        """
        with self._lock:
            char = self.char_time_s
            arrived, repeated = self._carry_request(payload, char)
            if repeated is not None:
                reply = repeated
            else:
                answer, _ = self._execute(payload)
                self._last_request = payload
                reply = self._last_payload = m.encode_reply(answer)
                self._last_reply = None  # built if a DLE ENQ or NAK asks for it again
            self._carry_reply(len(reply), arrived, char)
            return reply

    def _carry_request(self, payload: bytes, char_s: float) -> tuple[float, bytes | None]:
        """A carried request's wire time; when it arrived (s) and the kept reply if it repeats.

        The clock is moved to the request's arrival; a repeat of the last request (the PC
        sent it again) gets the kept reply payload, not another execution (None: execute).
        """
        arrived = self.rx_wire.send((len(payload) + _FRAME_OVERHEAD) * char_s)
        if payload == self._last_request and self._last_payload is not None:
            log.debug("duplicate request, reply repeated, not executed")
            return arrived, self._last_payload
        return arrived, None

    def _carry_reply(self, reply_size: int, arrived_s: float, char_s: float) -> None:
        """A carried answer's wire time; the clock moved to the reply's end.

        The DLE ACK and the reply as :meth:`_schedule` puts ``[ack, reply]``, then the
        PC's DLE ACK of the reply. ``reply_size``: the reply payload's length (bytes);
        ``arrived_s``: when the request arrived (s); ``char_s``: one character's time (s).
        """
        tx = self.tx_wire
        tx.send(2 * char_s, arrived_s)
        end = tx.send((reply_size + _FRAME_OVERHEAD) * char_s,
                      arrived_s + self.config.reply_latency_s)
        self.rx_wire.transmit(_ACK_SIZE * char_s, end)

    def carry_status(self, payload: bytes) -> m.Status | None:
        """:meth:`carry` of a READ_STATUS request payload; the status its reply carries.

        The same clock, wires, execution and retransmission rule, and the same reply
        payload kept for a repeat; the request is not decoded, the reply not built as a
        message, and the status handed over as ``parse_status`` would read it from the
        reply. None (nothing done) when the payload is not a well-formed READ_STATUS.
        """
        tns = m.status_request_transaction(payload)
        if tns is None:
            return None
        with self._lock:
            char = self.char_time_s
            arrived, repeated = self._carry_request(payload, char)
            if repeated is not None:
                status = m.parse_status(m.decode_reply(repeated).body)
                self._carry_reply(len(repeated), arrived, char)
                return status
            # _execute's READ_STATUS: the physics brought to now, then _read's status
            now = self.clock.now_s
            self.physics.advance_to(now)
            status = self._status(now)
            self._last_request = payload
            self._payload, self._status_reply = None, (tns, status)  # encoded if asked
            self._last_reply = None
            self._carry_reply(_STATUS_REPLY_SIZE, arrived, char)
            return status

    def _schedule(self, answers: list[Answer], arrived_s: float) -> None:
        """Put the answers on the controller-to-PC wire; move the clock to their end."""
        for answer in answers:
            ready = arrived_s if answer.kind != "reply" else arrived_s + self.config.reply_latency_s
            size = 2 if answer.kind != "reply" else _nominal_size(answer.wire)
            _, end = self.tx_wire.transmit(size * self.char_time_s, ready)
            self.clock.advance_to(end)
            if answer.kind == "reply":  # the PC acknowledges it at once (link rule 5)
                self.rx_wire.transmit(len(framing.Control.ACK.wire) * self.char_time_s, end)

    def _answers(self, frame: framing.Frame) -> list[Answer]:
        if isinstance(frame, framing.BadFrame):
            log.debug("NAK: %s", frame.reason)
            return [Answer("nak", framing.Control.NAK.wire)]
        if isinstance(frame, framing.Control):
            if frame is framing.Control.ACK:
                return []
            return [self._repeat()]
        ack = Answer("ack", framing.Control.ACK.wire)
        if frame.payload == self._last_request and self._last_payload is not None:
            log.debug("duplicate request, reply repeated, not executed")
            return [ack, self._repeat()]
        reply, executed = self._execute(frame.payload)
        self._last_request = frame.payload
        self._last_payload = m.encode_reply(reply)
        self._last_reply = framing.encode(self._last_payload)
        return [ack, Answer("reply", self._last_reply, executed)]

    def _repeat(self) -> Answer:
        if self._last_payload is None:
            return Answer("nak", framing.Control.NAK.wire)
        if self._last_reply is None:  # the reply went as a payload (carry)
            self._last_reply = framing.encode(self._last_payload)
        return Answer("reply", self._last_reply)

    def _execute(self, payload: bytes) -> tuple[m.Reply, bool]:
        """Run one request; returns the reply and whether the robot was commanded."""
        try:
            request = m.decode_request(payload)
        except ProtocolError as exc:
            header = m.peek_header(payload) or (0, 0)
            error = m.ErrorCode.BAD_REQUEST
            if header[0] not in {int(c) for c in m.Command}:
                error = m.ErrorCode.UNKNOWN_COMMAND
            return self._refuse(header[0], header[1], error, str(exc)), False
        now = self.clock.now_s
        self.physics.advance_to(now)
        motion = self.motion
        cmd, tns = request.command, request.transaction
        if cmd in (m.Command.MOVE_TO, m.Command.MOVE_BY):
            if cmd is m.Command.MOVE_TO:
                xyz, quaternion = m.parse_pose(request.body)
                target = Pose(*xyz, quaternion)
            else:
                target = motion.target.moved(*m.parse_increment(request.body))
            refusal = check_target(self.config, target)
            if refusal is not None:
                return self._refuse(cmd, tns, _REFUSAL_CODE[refusal[0]], refusal[1]), False
            motion.command(target, now)
            self.physics.advance_to(now)  # an instant arm is there at once
            self.move_count += 1
            self._last_error = 0
            return m.Reply(cmd, tns, m.ErrorCode.OK), True
        if cmd is m.Command.SET_SPEED:
            speed = m.parse_speed(request.body)
            if not 0 < speed <= self.config.max_speed_mm_s:
                reason = f"speed {speed} mm/s outside 0..{self.config.max_speed_mm_s}"
                return self._refuse(cmd, tns, m.ErrorCode.BAD_SPEED, reason), False
            motion.speed_mm_s = speed
            return m.Reply(cmd, tns, m.ErrorCode.OK), False
        if cmd is m.Command.STOP:
            motion.stop(now)
            return m.Reply(cmd, tns, m.ErrorCode.OK), False
        return m.Reply(cmd, tns, m.ErrorCode.OK, body=self._read(cmd, now)), False

    def _read(self, cmd: m.Command, now_s: float) -> bytes:
        """Body of the read-only replies."""
        motion = self.motion
        if cmd is m.Command.IDENTIFY:
            return m.identify_body(VERSION, MODEL)
        if cmd in (m.Command.READ_POSITION, m.Command.READ_TARGET):
            pose = motion.pose if cmd is m.Command.READ_POSITION else motion.target
            if cmd is m.Command.READ_TARGET:
                return m.pose_body((pose.x_mm, pose.y_mm, pose.z_mm), pose.quaternion)
            joints = joint_angles_deg(self.config, pose) or (float("nan"),) * 6
            xyz = (pose.x_mm, pose.y_mm, pose.z_mm)
            return m.position_body(m.Position(xyz, pose.quaternion, joints))
        return m.status_body(self._status(now_s))

    def _status(self, now_s: float) -> m.Status:
        """The controller's status at ``now_s`` (s), as READ_STATUS's reply carries it."""
        motion = self.motion
        in_position = motion.in_position and not self.never_in_position
        return m.Status(motion.moving, in_position, self._last_error,
                        self.move_count & 0xFFFFFFFF, now_s)

    def state_dict(self) -> dict[str, Any]:
        """The link's wire timelines (the motion is the physics' to save)."""
        with self._lock:
            return {"rx": self.rx_wire.state_dict(), "tx": self.tx_wire.state_dict()}

    def load_state_dict(self, state: dict[str, Any]) -> None:
        """Restore :meth:`state_dict`."""
        with self._lock:
            self.rx_wire.load_state_dict(state["rx"])
            self.tx_wire.load_state_dict(state["tx"])

    def _refuse(self, code: int, tns: int, error: m.ErrorCode, reason: str) -> m.Reply:
        log.info("refused command 0x%02X: %s", code, reason)
        self._last_error = int(error)
        return m.Reply(code, tns, error, reason=reason)


_FRAME_OVERHEAD = 7
"""DLE STX, the length byte, DLE ETX and the two check bytes around a payload."""
_STATUS_REPLY_SIZE = len(m.encode_ok_reply(m.Command.READ_STATUS, 0,
                                           m.status_body(m.Status(False, False, 0, 0))))
"""READ_STATUS's OK reply payload, bytes (fixed: its body is one struct)."""
_ACK_SIZE = len(framing.Control.ACK.wire)
"""The PC's DLE ACK of a reply, bytes."""


def _wire_size(frame: framing.Frame) -> int:
    """Bytes a received frame is charged on the wire (nominal; 2 for control or damaged frames).

    DLE stuffing (one more byte per 0x10 in the payload) is not charged: it
    depends on the transaction number, which a driver starts at random, and
    the clock must not (about one byte in 256; under 1 % of the line's time).
    """
    if isinstance(frame, framing.DataFrame):
        return len(frame.payload) + _FRAME_OVERHEAD
    return 2


def _nominal_size(wire: bytes) -> int:
    """The nominal size of an encoded data frame: its payload unstuffed, plus the overhead."""
    body = wire[2:-4]  # length byte and payload, stuffed
    return len(body) - body.count(b"\x10\x10") - 1 + _FRAME_OVERHEAD
