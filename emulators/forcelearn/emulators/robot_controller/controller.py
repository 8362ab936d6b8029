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
"""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass

from forcelearn.devices import Pose
from forcelearn.drivers.computer_link import framing
from forcelearn.drivers.computer_link import messages as m
from forcelearn.emulators.physics.cell import CellPhysics
from forcelearn.emulators.robot_controller.kinematics import (
    ArmConfig,
    Servo,
    check_target,
    joint_angles_deg,
)
from forcelearn.errors import ProtocolError

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
        config: arm geometry, limits and servo settings.
        physics: shared cell physics; receives every pose the robot reaches.
        clock: monotonic clock in seconds (injectable for tests).
    """

    def __init__(
        self,
        config: ArmConfig | None = None,
        physics: CellPhysics | None = None,
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        self.config = config or ArmConfig()
        self.physics = physics or CellPhysics(pose=self.config.home)
        self._clock = clock
        self._lock = threading.RLock()
        self._servo = Servo(self.config, clock())
        self.physics.set_pose(self._servo.pose)
        self._last_request: bytes | None = None
        self._last_reply: bytes | None = None
        self._last_error = 0
        self.move_count = 0
        """Moves executed (accepted MOVE_TO / MOVE_BY); retransmissions never count."""

    @property
    def pose(self) -> Pose:
        """The pose the robot has reached."""
        with self._lock:
            self.tick()
            return self._servo.pose

    def tick(self) -> None:
        """Advance the servo to now and publish the reached pose to the physics."""
        with self._lock:
            before = self._servo.pose
            self._servo.advance(self._clock())
            if self._servo.pose != before:
                self.physics.set_pose(self._servo.pose)

    def handle(self, frame: framing.Frame) -> list[Answer]:
        """Return what to send in answer to one received frame."""
        with self._lock:
            if isinstance(frame, framing.BadFrame):
                log.debug("NAK: %s", frame.reason)
                return [Answer("nak", framing.Control.NAK.wire)]
            if isinstance(frame, framing.Control):
                if frame is framing.Control.ACK:
                    return []
                return [self._repeat()]
            ack = Answer("ack", framing.Control.ACK.wire)
            if frame.payload == self._last_request and self._last_reply is not None:
                log.debug("duplicate request, reply repeated, not executed")
                return [ack, self._repeat()]
            reply, executed = self._execute(frame.payload)
            self._last_request = frame.payload
            self._last_reply = framing.encode(m.encode_reply(reply))
            return [ack, Answer("reply", self._last_reply, executed)]

    def _repeat(self) -> Answer:
        if self._last_reply is None:
            return Answer("nak", framing.Control.NAK.wire)
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
        self.tick()
        now = self._clock()
        cmd, tns = request.command, request.transaction
        if cmd in (m.Command.MOVE_TO, m.Command.MOVE_BY):
            if cmd is m.Command.MOVE_TO:
                xyz, quaternion = m.parse_pose(request.body)
                target = Pose(*xyz, quaternion)
            else:
                target = self._servo.target.moved(*m.parse_increment(request.body))
            refusal = check_target(self.config, target)
            if refusal is not None:
                return self._refuse(cmd, tns, _REFUSAL_CODE[refusal[0]], refusal[1]), False
            self._servo.command(target, now)
            self.physics.set_pose(self._servo.pose)
            self.move_count += 1
            self._last_error = 0
            return m.Reply(cmd, tns, m.ErrorCode.OK), True
        if cmd is m.Command.SET_SPEED:
            speed = m.parse_speed(request.body)
            if not 0 < speed <= self.config.max_speed_mm_s:
                reason = f"speed {speed} mm/s outside 0..{self.config.max_speed_mm_s}"
                return self._refuse(cmd, tns, m.ErrorCode.BAD_SPEED, reason), False
            self._servo.speed_mm_s = speed
            return m.Reply(cmd, tns, m.ErrorCode.OK), False
        if cmd is m.Command.STOP:
            self._servo.stop(now)
            return m.Reply(cmd, tns, m.ErrorCode.OK), False
        return m.Reply(cmd, tns, m.ErrorCode.OK, body=self._read(cmd)), False

    def _read(self, cmd: m.Command) -> bytes:
        """Body of the read-only replies."""
        servo = self._servo
        if cmd is m.Command.IDENTIFY:
            return m.identify_body(VERSION, MODEL)
        if cmd is m.Command.READ_POSITION:
            pose = servo.pose
            joints = joint_angles_deg(self.config, pose) or (float("nan"),) * 6
            xyz = (pose.x_mm, pose.y_mm, pose.z_mm)
            return m.position_body(m.Position(xyz, pose.quaternion, joints))
        in_position = not servo.moving
        return m.status_body(
            m.Status(servo.moving, in_position, self._last_error, self.move_count)
        )

    def _refuse(self, code: int, tns: int, error: m.ErrorCode, reason: str) -> m.Reply:
        log.info("refused command 0x%02X: %s", code, reason)
        self._last_error = int(error)
        return m.Reply(code, tns, error, reason=reason)
