"""The driver's side of an EGM session as pure state: datagrams in, the next reply out (no I/O).

:class:`Guidance` is fed every EgmRobot datagram (:meth:`Guidance.on_datagram`)
and builds the EgmSensor answer (:meth:`Guidance.reply`). Rules:

* The first datagram, and any later one with ``seqno == 0``, starts a
  **session**: the reply seqno restarts at 0 and target and planned pose are
  set to the feedback pose, so a restarted controller is held where it is.
* A datagram is **fresh** (and answered) only if its seqno is newer than the
  latest one (mod 2**32). Skipped seqnos count as ``missed``; an equal seqno
  is a ``duplicate``; an older one is ``out_of_order``; neither is answered
  nor allowed to overwrite newer feedback.
* Every reply moves the planned pose toward the target by at most
  ``speed_mm_s`` x ``sample_period_s`` (and ``TURN_DEG_S`` x period in
  orientation): the controller is never asked for a jump.
* In position: the planned pose has reached the target, and the controller's
  feedback and its own planned pose are within ``in_position_mm`` /
  ``in_position_deg`` of it.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, replace
from typing import Any

import numpy as np

from forcelearn.devices import Pose
from forcelearn.drivers.egm.config import EgmConfig
from forcelearn.errors import GuidanceStopped, ProtocolError
from forcelearn.protocols.egm import codec

TURN_DEG_S = 45.0
"""Largest rate at which the planned orientation turns toward the target (assumption)."""

_SEQNO_MOD = 1 << 32


@dataclass(frozen=True)
class EgmStats:
    """Counters of one driver's traffic since it opened."""

    received: int = 0
    """EgmRobot datagrams received (fresh or not)."""
    replies: int = 0
    """EgmSensor datagrams sent."""
    missed: int = 0
    """Controller seqnos skipped (lost, or still to arrive out of order)."""
    duplicates: int = 0
    out_of_order: int = 0
    """Datagrams older than the latest one; ignored."""
    sessions: int = 0
    """Sessions seen (1 after opening; +1 per controller restart)."""
    bad_datagrams: int = 0
    """Datagrams that were not a readable EgmRobot; ignored."""


def angle_deg(q0: tuple[float, ...], q1: tuple[float, ...]) -> float:
    """Rotation angle between two unit quaternions, degrees."""
    dot = abs(float(np.dot(q0, q1)))
    return math.degrees(2.0 * math.acos(min(1.0, dot)))


def step_toward(pose: Pose, target: Pose, max_mm: float, max_deg: float) -> Pose:
    """Return ``pose`` moved toward ``target`` by at most ``max_mm`` and ``max_deg``."""
    error = target.position_mm - pose.position_mm
    distance = float(np.linalg.norm(error))
    turn = angle_deg(pose.quaternion, target.quaternion)
    if distance <= max_mm and turn <= max_deg:
        return target
    fraction = min(
        max_mm / distance if distance > 0 else 1.0, max_deg / turn if turn > 0 else 1.0
    )
    position = pose.position_mm + fraction * error
    q0, q1 = np.asarray(pose.quaternion), np.asarray(target.quaternion)
    if np.dot(q0, q1) < 0:
        q1 = -q1
    q = q0 + fraction * (q1 - q0)
    q = q / np.linalg.norm(q)
    x, y, z = (float(c) for c in position)
    w, qx, qy, qz = (float(c) for c in q)
    return Pose(x, y, z, (w, qx, qy, qz))


class Guidance:
    """What the driver knows of the controller and what it asks of it. Not thread-safe."""

    def __init__(self, config: EgmConfig) -> None:
        self.config = config
        self.latest: codec.RobotMessage | None = None
        self.latest_raw: bytes | None = None
        """The datagram ``latest`` was decoded from (what a checkpoint keeps)."""
        self.target: Pose | None = None
        """Last accepted target (the step limit is measured from it)."""
        self.planned: Pose | None = None
        """Planned pose of the last reply (ramps toward ``target``)."""
        self.speed_mm_s = config.speed_mm_s
        self.session = 0
        self.stats = EgmStats()
        self._next_seqno = 0
        self.origin_us: int | None = None
        """feedBack.time (µs since 1970) of the first message that had one: controller time 0."""

    # -- input ------------------------------------------------------------------------------

    def on_datagram(self, data: bytes) -> bool:
        """Take one EgmRobot datagram; True if it is fresh and must be answered.

        Raises ``EgmVersionMismatch`` if it proves the other egm.proto, and
        ``ProtocolError`` if a session starts without a Cartesian feedback pose.
        """
        self._count(received=1)
        codec.check_version(data, self.config.version)
        try:
            message = codec.decode_robot(data, self.config.version)
        except ProtocolError:
            self._count(bad_datagrams=1)
            return False
        if self.origin_us is None and message.time_us is not None:
            self.origin_us = message.time_us
        latest = self.latest
        if latest is None or (message.seqno == 0 and latest.seqno != 0):
            self._start_session(message)
            self.latest_raw = data
            return True
        ahead = (message.seqno - latest.seqno) % _SEQNO_MOD
        if ahead == 0:
            self._count(duplicates=1)
            return False
        if ahead >= _SEQNO_MOD // 2:
            self._count(out_of_order=1)
            return False
        self._count(missed=ahead - 1)
        self.latest = message
        self.latest_raw = data
        return True

    def _start_session(self, message: codec.RobotMessage) -> None:
        if message.feedback is None:
            raise ProtocolError(
                "EgmRobot without feedBack.cartesian: run EGMSetupUC with \\Pose "
                "(rapid/ForcelearnEGM.modx), not \\Joint"
            )
        self.latest = message
        self.target = self.planned = message.feedback
        self.session += 1
        self._next_seqno = 0
        self._count(sessions=1)

    def _count(self, **increments: int) -> None:
        stats = self.stats
        self.stats = replace(
            stats, **{k: getattr(stats, k) + v for k, v in increments.items()}
        )

    # -- output -----------------------------------------------------------------------------

    def reply(self) -> bytes:
        """Return the EgmSensor answering the latest message, one ramp step nearer the target."""
        if self.latest is None or self.planned is None or self.target is None:
            raise RuntimeError("no EGM session yet: nothing to answer")
        period = self.config.sample_period_s
        self.planned = step_toward(
            self.planned, self.target, self.speed_mm_s * period, TURN_DEG_S * period
        )
        message = codec.SensorMessage(self._next_seqno, self.latest.tm_ms, self.planned)
        self._next_seqno = (self._next_seqno + 1) % _SEQNO_MOD
        self._count(replies=1)
        return codec.encode_sensor(message, self.config.version)

    def hold(self) -> None:
        """Make the present feedback pose both target and planned pose."""
        if self.latest is not None and self.latest.feedback is not None:
            self.target = self.planned = self.latest.feedback

    # -- checkpoint (an emulated cell's bit-identical resume) -------------------------------

    def state_dict(self) -> dict[str, Any]:
        """The session as JSON-able values (the latest datagram as hex)."""

        def pose(p: Pose | None) -> list[float] | None:
            return None if p is None else [p.x_mm, p.y_mm, p.z_mm, *p.quaternion]

        return {
            "latest": None if self.latest_raw is None else self.latest_raw.hex(),
            "target": pose(self.target),
            "planned": pose(self.planned),
            "speed_mm_s": self.speed_mm_s,
            "session": self.session,
            "next_seqno": self._next_seqno,
            "origin_us": self.origin_us,
            "stats": asdict(self.stats),
        }

    def load_state_dict(self, state: dict[str, Any]) -> None:
        """Restore :meth:`state_dict`."""

        def pose(v: list[float] | None) -> Pose | None:
            if v is None:
                return None
            x, y, z, w, qx, qy, qz = (float(c) for c in v[:7])
            return Pose(x, y, z, (w, qx, qy, qz))

        raw = state["latest"]
        self.latest_raw = None if raw is None else bytes.fromhex(raw)
        self.latest = (
            None if self.latest_raw is None
            else codec.decode_robot(self.latest_raw, self.config.version)
        )
        self.target = pose(state["target"])
        self.planned = pose(state["planned"])
        self.speed_mm_s = float(state["speed_mm_s"])
        self.session = int(state["session"])
        self._next_seqno = int(state["next_seqno"])
        origin = state.get("origin_us")
        self.origin_us = None if origin is None else int(origin)
        self.stats = EgmStats(**state["stats"])

    # -- queries ----------------------------------------------------------------------------

    def controller_time_s(self) -> float:
        """The controller's time of the latest message, s: feedBack.time, else header.tm.

        feedBack.time is the controller's clock in µs since 1970 (manual
        3HAC073318 p.38); it is counted from the first message the driver
        read (:attr:`origin_us`) in whole µs, so differences keep full
        resolution. The clock itself is :attr:`controller_clock_us`.
        """
        if self.latest is None:
            return 0.0
        if self.latest.time_us is not None and self.origin_us is not None:
            return (self.latest.time_us - self.origin_us) / 1e6
        return self.latest.tm_ms / 1000.0

    def controller_clock_us(self) -> int | None:
        """feedBack.time of the latest message: µs since 1970-01-01 UTC (None if not sent)."""
        return None if self.latest is None else self.latest.time_us

    def require_running(self) -> None:
        """Raise ``GuidanceStopped`` unless motors are on, EGM runs and RAPID runs.

        RAPID_UNDEFINED is accepted, as abb_libegm does (a controller-restart quirk).
        """
        m = self.latest
        if m is None:
            return
        if (
            m.motor is not codec.MotorState.ON
            or m.mci is not codec.MciState.RUNNING
            or m.rapid is codec.RapidState.STOPPED
        ):
            raise GuidanceStopped(
                f"the controller is not guided: motors {m.motor.name}, EGM {m.mci.name}, "
                f"RAPID {m.rapid.name}; restart the ForcelearnEGM RAPID program "
                "(after a comm timeout, check the PC address and firewall)"
            )

    def in_position(self) -> bool:
        """True when planned, the controller's planned and its feedback are all at the target."""
        m, target = self.latest, self.target
        if m is None or target is None or m.feedback is None or self.planned != target:
            return False
        poses = [m.feedback] + ([m.planned] if m.planned is not None else [])
        band_mm, band_deg = self.config.in_position_mm, self.config.in_position_deg
        return all(
            float(np.linalg.norm(p.position_mm - target.position_mm)) <= band_mm
            and angle_deg(p.quaternion, target.quaternion) <= band_deg
            for p in poses
        )
