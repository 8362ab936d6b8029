"""ABB robot over Externally Guided Motion (EGM): a ``forcelearn.devices.Robot`` over UDP.

::

    with open_egm_robot(EgmConfig(host="192.168.125.10", version="rw6")) as robot:
        robot.move_to(robot.read_pose().moved(dz_mm=-1.0))
        robot.wait_in_position(timeout_s=2.0, settle_s=0.05)

The driver is :class:`EgmRobot` (named as the other drivers are, after its
device; ``EgmRobotDriver`` is its old name), not to be confused with the
protocol's EgmRobot message. The PC is the UDP server: the driver binds
``host:port`` and the controller sends an EgmRobot message every sample
period; each fresh one is answered with an EgmSensor whose planned pose ramps
toward the last accepted target (:mod:`.guidance`). Only the paired controller
is answered (``controller_host`` / ``controller_port``, else the first sender
of a valid session start), and no datagram ends a session: what cannot be used
is counted in :class:`EgmStats`.
``move_to`` only sets the target: it is checked in full at the call first
(``InvalidTarget`` / ``SafetyStop``, and no datagram ever carries a refused
target). Two modes:

* **real** (``lockstep = False``): a receive thread answers every message at
  once with the latest planned pose, as abb_libegm does; the controller's
  clock runs on its own.
* **lockstep** (the emulated cell): nothing answers between calls; calls that
  let time pass (:meth:`EgmRobot.wait_in_position`,
  :meth:`EgmRobot.dwell`) answer the held message and read the next
  one, so the controller cycles spent between two host actions are fixed by
  the traffic alone (docs/egm.md, "Lockstep").

Errors: ``InvalidTarget`` (a malformed target or one outside the workspace,
at the call, nothing sent), ``SafetyStop`` (step or speed limit; or the
controller's session start was refused for feedback outside the workspace or
not finite), ``LinkTimeout`` (the controller fell silent for ``watchdog_s``,
feedback is stale, or not in position in time), ``GuidanceStopped`` (motors
off, EGM stopped, RAPID stopped, or a controller restart dropped the target),
``EgmVersionMismatch`` (only the other RobotWare's datagrams came),
``ProtocolError``, ``LinkError`` (socket, or the receive thread ended).

This module holds the robot calls; the datagram exchange under them (socket,
receive thread, lockstep cycles, watchdog, session wait) is :mod:`.channel`.
"""

from __future__ import annotations

import contextlib
import math
import time
from dataclasses import dataclass
from typing import Any

import numpy as np

from forcelearn.deprecation import renamed
from forcelearn.devices import InPositionWait, Pose
from forcelearn.drivers.egm.channel import MAX_DATAGRAM, POLL_S, DatagramSocket, EgmChannel
from forcelearn.drivers.egm.config import EgmConfig
from forcelearn.drivers.egm.stats import EgmStats
from forcelearn.drivers.egm.targets import clean_target, unsafe_reason
from forcelearn.drivers.lifecycle import opened
from forcelearn.drivers.targets import TARGET_NORM_TOLERANCE
from forcelearn.errors import (
    GuidanceStopped,
    InvalidTarget,
    LinkTimeout,
    NotInPosition,
    SafetyStop,
)
from forcelearn.protocols.egm import codec

__all__ = [
    "MAX_DATAGRAM", "POLL_S", "DatagramSocket", "EgmRobot", "EgmStatus", "open_egm_robot",
]


@dataclass(frozen=True)
class EgmStatus:
    """The controller's state as of its latest message, and the driver's counters."""

    motor: codec.MotorState
    mci: codec.MciState
    rapid: codec.RapidState
    convergence_met: bool | None
    utilization_pct: float | None
    measured_force: tuple[float, ...] | None
    """measuredForce.force, N and N·m. RW7 with ``fc_active`` false: the raw sensor force
    ("Will show raw sensor force when force control is not active", manual p.36), kept."""
    in_position: bool
    controller_time_s: float
    """Controller time since the driver's first message, s (feedBack.time differences)."""
    seqno: int
    stats: EgmStats
    fc_active: bool | None = None
    """RW7 measuredForce.fcActive: the controller's Force Control is active (None: RW6)."""
    controller_clock_us: int | None = None
    """feedBack.time: the controller's clock, µs since 1970-01-01 UTC (None if not sent)."""
    joints_deg: tuple[float, ...] = ()
    """feedBack.joints: the measured axes, degrees (empty if not sent)."""
    planned_joints_deg: tuple[float, ...] = ()
    """planned.joints: the planned axes, degrees (empty if not sent)."""


class EgmRobot(EgmChannel):
    """Driver of one robot over one EGM UDP channel (satisfies ``Robot`` once a session runs).

    Constructing it binds the socket (:class:`~.channel.EgmChannel`);
    :meth:`wait_for_session` (or :meth:`open`, or entering ``with``) then
    waits for the controller's first message. :func:`open_egm_robot` does
    both.
    """

    def __init__(self, config: EgmConfig, sock: DatagramSocket | None = None) -> None:
        super().__init__(config, sock)
        self.last_wait: InPositionWait | None = None
        """How the last :meth:`wait_in_position` ended: when in position, and the feedback pose."""

    # -- reading ----------------------------------------------------------------------------

    def read_pose(self) -> Pose:
        """Return the controller's feedback pose (mm, quaternion w x y z)."""
        with self._lock:
            feedback = self._latest().feedback
            assert feedback is not None  # a session starts only with one; decode keeps it
            return feedback

    def read_joints_deg(self) -> tuple[float, ...]:
        """Return the joint angles of the latest feedback, degrees (empty if not sent)."""
        with self._lock:
            return self._latest().joints_deg

    def read_status(self) -> EgmStatus:
        """Return the controller's states, the in-position flag and the traffic counters."""
        with self._lock:
            m = self._latest()
            return EgmStatus(
                motor=m.motor,
                mci=m.mci,
                rapid=m.rapid,
                convergence_met=m.convergence_met,
                utilization_pct=m.utilization_pct,
                measured_force=m.measured_force,
                in_position=self._guidance.in_position(),
                controller_time_s=self._guidance.controller_time_s(),
                seqno=m.seqno,
                stats=self._guidance.stats,
                fc_active=m.fc_active,
                controller_clock_us=m.time_us,
                joints_deg=m.joints_deg,
                planned_joints_deg=m.planned_joints_deg,
            )

    @property
    def stats(self) -> EgmStats:
        """Traffic counters: received, replies, missed... and each kind of datagram ignored."""
        with self._lock:
            return self._guidance.stats

    @property
    def controller_address(self) -> Any:
        """The paired controller's source address (host, port); None before the first session."""
        with self._lock:
            return self._guidance.controller

    @property
    def target(self) -> Pose | None:
        """The last accepted target."""
        with self._lock:
            return self._guidance.target

    # -- commanding -------------------------------------------------------------------------

    def move_to(self, pose: Pose) -> None:
        """Set a new target; the planned pose ramps to it at the set speed.

        Returns at once: use :meth:`wait_in_position` to know when it is reached.

        Raises:
            InvalidTarget: not a Pose of finite numbers with a unit 4-element
                quaternion, or outside the workspace box (nothing sent).
            SafetyStop: a step longer than ``limits.max_step_mm`` (nothing sent).
        """
        target = clean_target(pose)
        with self._lock:
            self._latest()
            self._guidance.require_running()
            self._check_target(target)
            self._guidance.target = target

    def move_by(self, dx_mm: float = 0.0, dy_mm: float = 0.0, dz_mm: float = 0.0) -> None:
        """Move the target by an increment, orientation kept (mm; checked as ``move_to``)."""
        with self._lock:
            self._latest()
            assert self._guidance.target is not None
            base = self._guidance.target
            try:
                moved = base.moved(dx_mm, dy_mm, dz_mm)
            except TypeError:
                raise InvalidTarget(
                    f"move_by takes numbers of mm, got {dx_mm!r}, {dy_mm!r}, {dz_mm!r}; "
                    "nothing was sent"
                ) from None
            self.move_to(moved)

    def set_speed(self, speed_mm_s: float) -> None:
        """Set the ramp speed of the planned pose, mm/s (refused above limits.max_speed_mm_s)."""
        limit = self.config.limits.max_speed_mm_s
        valid = isinstance(speed_mm_s, int | float) and not isinstance(speed_mm_s, bool)
        if not (valid and math.isfinite(speed_mm_s) and 0 < speed_mm_s <= limit):
            raise SafetyStop(
                f"refused speed {speed_mm_s!r} mm/s: allowed 0..{limit} (limits.max_speed_mm_s); "
                "nothing was sent"
            )
        with self._lock:
            self._guidance.speed_mm_s = float(speed_mm_s)

    def _check_target(self, target: Pose) -> None:
        """Raise InvalidTarget or SafetyStop if ``target`` breaks a limit (it is never sent)."""
        limits = self.config.limits
        reason = unsafe_reason(target, limits, TARGET_NORM_TOLERANCE)
        if reason is not None:
            raise InvalidTarget(f"refused target: {reason}; nothing was sent")
        reference = self._guidance.target
        assert reference is not None
        step = float(np.linalg.norm(target.position_mm - reference.position_mm))
        if not step <= limits.max_step_mm:
            raise SafetyStop(
                f"refused a step of {step:.3f} mm: more than limits.max_step_mm = "
                f"{limits.max_step_mm} mm; nothing was sent"
            )

    def stop(self) -> None:
        """Hold the present feedback pose (target and planned pose both become it)."""
        with self._lock:
            self._check()
            self._guidance.hold()

    # -- waiting (lets controller time pass) ------------------------------------------------

    def wait_in_position(self, timeout_s: float, settle_s: float = 0.0) -> float:
        """Wait until in position for ``settle_s`` of controller time; return that time (s).

        Both times are the controller's (its feedBack.time): ``NotInPosition``
        (the pose held) if not in position within ``timeout_s``,
        ``GuidanceStopped`` if guidance stops or the controller starts a new
        session meanwhile.
        """
        if not (timeout_s > 0 and settle_s >= 0):
            raise ValueError(f"need timeout_s > 0 and settle_s >= 0, got {timeout_s}, {settle_s}")
        with self._lock:
            self._wait(timeout_s, settle_s, until_in_position=True)
            return self._guidance.controller_time_s()

    def read_target(self) -> Pose:
        """Return the target the planned pose ramps to (the reference for relative moves)."""
        with self._lock:
            self._latest()
            target = self._guidance.target
            return target if target is not None else self.read_pose()

    def dwell(self, duration_s: float) -> Pose:
        """Let ``duration_s`` of controller time pass while guiding; return the feedback pose."""
        if not duration_s >= 0:
            raise ValueError(f"duration_s must be >= 0, got {duration_s}")
        with self._lock:
            return self._wait(duration_s, 0.0, until_in_position=False)

    def wait_for_guidance(self, span_s: float) -> Pose:
        """Answer the controller until it guides again (a new session); return its feedback pose.

        After a CommTimeout (or any stop) the controller holds the robot; its RAPID
        program opens a new session when it restarts (rapid/ForcelearnEGM.modx does
        so by itself). Waits up to ``span_s`` of controller time.

        Raises:
            GuidanceStopped: still not guided after ``span_s``.
            LinkTimeout: the controller fell silent (``watchdog_s``), or its time did not
                advance ``span_s`` in wall time.
        """
        if not span_s > 0:
            raise ValueError(f"span_s must be > 0, got {span_s}")
        with self._lock:
            guidance = self._guidance
            self._latest()
            start = guidance.controller_time_s()
            wall_deadline = time.monotonic() + span_s + self.config.watchdog_s + 1.0
            while True:
                self._check()
                try:
                    guidance.require_running()
                    return self.read_pose()
                except GuidanceStopped:
                    if guidance.controller_time_s() - start >= span_s:
                        raise
                if time.monotonic() > wall_deadline:
                    raise LinkTimeout(f"controller time did not advance {span_s} s in wall time")
                self._next_message()

    def _wait(self, span_s: float, settle_s: float, until_in_position: bool) -> Pose:
        try:
            reached = self._wait_cycles(span_s, settle_s, until_in_position)
        except BaseException:
            with contextlib.suppress(RuntimeError):  # the error that ended the wait comes first
                self._guidance.finish_latest()
            raise
        self._guidance.finish_latest()
        return reached

    def _wait_cycles(self, span_s: float, settle_s: float, until_in_position: bool) -> Pose:
        guidance = self._guidance
        self._latest()
        session = guidance.session
        wait = _Waiting(guidance.controller_time_s(), span_s, settle_s)
        wall_deadline = time.monotonic() + span_s + self.config.watchdog_s + 1.0
        while True:
            self._check()
            if guidance.session != session:
                raise GuidanceStopped(
                    "the controller started a new EGM session (seqno 0: a restart) during the "
                    "wait; the target was dropped and the robot held where it is"
                )
            guidance.require_running()
            now = guidance.controller_time_s()
            if until_in_position and wait.settled(now, guidance.in_position()):
                reached = self.read_pose()
                assert wait.settled_since is not None
                self.last_wait = InPositionWait(wait.settled_since, reached)
                return reached
            if wait.spent(now):
                if not until_in_position:
                    return self.read_pose()
                self._guidance.hold()
                raise NotInPosition(
                    f"not in position within {span_s} s of controller time: feedback "
                    f"{self.read_pose()}, target {guidance.target}"
                )
            if time.monotonic() > wall_deadline:
                raise LinkTimeout(f"controller time did not advance {span_s} s in wall time")
            if self._rester is not None:  # in process: the cycles it only answers, in one jump
                self._rest_during(wait, until_in_position)
            self._next_message()

    def _rest_during(self, wait: _Waiting, until_in_position: bool) -> None:
        """Jump the cycles at which ``wait``'s loop would only answer again (:meth:`_rest`)."""
        guidance = self._guidance
        in_position_at, settled, spent = guidance.in_position_at, wait.settled, wait.spent

        def ends(times: list[float], feedback: Pose, planned: Pose) -> int:
            # the wait's end test at each of times in turn (in position: the same poses)
            in_position = until_in_position and in_position_at(feedback, planned)
            for index, now in enumerate(times):
                if (until_in_position and settled(now, in_position)) or spent(now):
                    return index
            return len(times)

        self._rest(ends)

    # -- checkpoint (emulated cell only) ----------------------------------------------------

    def state_dict(self) -> dict[str, Any]:
        """The guidance session (latest feedback, target, planned pose, speed, seqno), JSON-able.

        For the emulated cell's bit-identical resume, where the driver and the
        emulator are restored together; a real controller cannot be restored.
        """
        with self._lock:
            return self._guidance.state_dict()

    def load_state_dict(self, state: dict[str, Any]) -> None:
        """Restore :meth:`state_dict` (lockstep only, between calls, a session open)."""
        if not self.config.lockstep:
            raise ValueError("only a lockstep (emulated) EGM session can be restored")
        with self._lock:
            self._check()
            self._guidance.load_state_dict(state)


@dataclass
class _Waiting:
    """A wait's progress in controller time (s): its start, span and settling."""

    start: float
    span_s: float
    settle_s: float
    settled_since: float | None = None
    """Since when in position without a break (None: not in position)."""

    def settled(self, now: float, in_position: bool) -> bool:
        """Note whether a message of time ``now`` is in position; True once settled long enough."""
        if not in_position:
            self.settled_since = None
            return False
        if self.settled_since is None:
            self.settled_since = now
        return now - self.settled_since >= self.settle_s - 1e-9

    def spent(self, now: float) -> bool:
        """Whether the span has run out at a message of time ``now``."""
        return now - self.start >= self.span_s - 1e-9


def open_egm_robot(config: EgmConfig, timeout_s: float | None = None) -> EgmRobot:
    """Bind, wait for the controller's first message and return the ready driver.

    ``timeout_s`` replaces ``config.first_message_timeout_s``; the driver is
    closed if no session starts.
    """
    if timeout_s is None:
        return opened(EgmRobot(config))
    driver = EgmRobot(config)
    try:
        driver.wait_for_session(timeout_s)
    except BaseException:
        driver.close()
        raise
    return driver


__getattr__ = renamed(__name__, {"EgmRobotDriver": EgmRobot})
