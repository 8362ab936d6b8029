r"""The controller's side of EGM pose guidance as pure state: times in, datagrams out (no I/O).

It reuses the driver's codec (the protocol itself) and nothing else of the
driver. One :class:`EgmControllerModel` is one robot running
``rapid/ForcelearnEGM.modx`` (EGMActPose \\StreamStart + EGMRunPose):

* every cycle :meth:`EgmControllerModel.robot_datagram` advances the motion
  model to the cycle's time, publishes the reached pose to the shared
  ``CellPhysics`` and returns the EgmRobot (seqno +1 per message, 0 at the
  start of a session; feedBack.time and header.tm from the simulated clock);
* :meth:`EgmControllerModel.apply_sensor` takes an EgmSensor's planned pose
  at the cycle that reads it; a pose outside the workspace box, or with a
  non-unit quaternion, puts EGM in MCI_ERROR and holds the robot (the real
  controller stops with a motion error);
* **CommTimeout**: when no EgmSensor has been read for ``comm_timeout_s``,
  guidance ends: the robot holds, MCI_STOPPED and RAPID_STOPPED are reported
  (EGMRunPose raised ERR_UDPUC_COMM and the program stopped), the stream goes
  on (\\StreamStart), and EgmSensor datagrams are ignored until
  :meth:`EgmControllerModel.restart` (the operator restarts the program:
  a new session, seqno 0). With ``restart_after_s`` the RAPID program's ERROR
  handler does that itself (``rapid/ForcelearnEGM.modx``: EGMReset, WaitTime,
  guidance again from where the robot holds) that long after the timeout.

What every EgmRobot carries beside the poses (manual 3HAC073318 RW7, p.35-38):

* ``feedBack.joints`` / ``planned.joints``: the six axes in degrees, from
  the cell's arm model (:mod:`.joints`), for the reached and the planned pose;
* ``feedBack.time``: the controller's clock, seconds and microseconds since
  1970-01-01 UTC: ``clock_epoch_us`` (the cell's start, default
  2026-01-01T00:00:00Z, fixed so that runs stay byte-identical) plus the
  simulated time; ``planned.time`` ("when the robot will be in the planned
  position") is that plus the control lag;
* RW7 ``measuredForce``: ``fcActive`` is true only while the controller's own
  Force Control runs (``force_control_active``; ForcelearnEGM.modx runs none),
  and ``force`` holds the sensor force either way ("Will show raw sensor force
  when force control is not active", p.36).

What an EgmSensor is taken for (the mode is EGMSetupUC's ``\\Pose`` or
``\\Joint``, ``mode``):

* pose mode: ``planned.cartesian``; joint mode: ``planned.joints`` (six
  angles in degrees, checked against the axis ranges, then reached through
  the arm's forward kinematics). A datagram with only the other mode's field
  carries no position data for this mode: the controller keeps the latest
  reference (p.26: "If no position data had been sent, motion control
  continues to use the latest position data"); it is counted in
  ``wrong_mode`` and logged, never silently dropped;
* ``speedRef``: the speed feed-forward of the control law
  ``speed = k * (pos_ref - pos) + speed_ref`` (p.26). With the servo's
  first-order lag of time constant tau (k = 1 / tau) this is exactly the lag
  acting toward ``pos_ref + speed_ref * tau``, which is how it is applied
  (cartesian mm/s and deg/s in pose mode; in joint mode the joints led by
  deg/s x tau, through the forward kinematics, since the servo lags in
  Cartesian space). A speedRef without six finite values is not used.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace
from typing import Any, Literal

from forcelearn.devices import Pose
from forcelearn.emulators.egm import joints as arm_joints
from forcelearn.emulators.egm.servo import LagServo, MotionModel, ServoParams, feed_forward_pose
from forcelearn.emulators.egm.target_checks import TargetChecks
from forcelearn.emulators.physics.arm import ArmConfig, joint_angles_deg
from forcelearn.emulators.physics.cell import CellPhysics
from forcelearn.errors import ProtocolError
from forcelearn.protocols.egm import carried, codec

log = logging.getLogger(__name__)

HOME = Pose(900.0, 0.0, 600.0, (0.0, 1.0, 0.0, 0.0))
"""Start pose when no physics is given: 900 mm out, 600 mm up, tool down (as the S3 emulator)."""

CONVERGENCE_MM = 1.0
"""EGMActPose convergence default (±1 mm, manual p.58): sets mciConvergenceMet."""

DEFAULT_CLOCK_EPOCH_US = 1_767_225_600_000_000
"""The controller clock at the cell's start: 2026-01-01T00:00:00Z in µs since 1970 (fixed)."""

Mode = Literal["pose", "joint"]
MODES: tuple[Mode, ...] = ("pose", "joint")


@dataclass(frozen=True)
class EgmControllerConfig:
    """Settings of the emulated controller (s, mm, mm/s)."""

    version: codec.Version = "rw7"
    """Which egm.proto it speaks."""
    sample_period_s: float = 0.004
    """EGMActPose \\SampleRate: 4 ms default, multiples of 4 ms."""
    comm_timeout_s: float = 1.0
    """EGMSetupUC \\CommTimeout (the manual states no default; 1 s is an assumption)."""
    restart_after_s: float | None = None
    """After a CommTimeout, a new session starts this long later, s (the RAPID program's ERROR
    handler re-opens guidance, as ``rapid/ForcelearnEGM.modx`` does); None: the program stops
    and waits for the operator (:meth:`EgmControllerModel.restart`)."""
    servo: ServoParams = field(default_factory=ServoParams)
    workspace_min_mm: tuple[float, float, float] = (300.0, -800.0, -200.0)
    workspace_max_mm: tuple[float, float, float] = (1500.0, 800.0, 1400.0)
    max_speed_mm_s: float = 1000.0
    """TCP speed that counts as 100 % utilizationRate (assumption)."""
    send_measured_force: bool = True
    """Send measuredForce (the physics' true wrench as the controller's sensor force)."""
    force_control_active: bool = False
    """RW7 fcActive: the controller's own Force Control runs (ForcelearnEGM.modx runs none)."""
    mode: Mode = "pose"
    """EGMSetupUC \\Pose (planned.cartesian guides) or \\Joint (planned.joints guides)."""
    clock_epoch_us: int = DEFAULT_CLOCK_EPOCH_US
    """feedBack.time at simulated time 0, µs since 1970-01-01 UTC."""
    arm: ArmConfig = field(default_factory=ArmConfig)
    """The arm whose six axes are reported (geometry and axis ranges; :mod:`.joints`)."""

    def __post_init__(self) -> None:
        if self.version not in codec.VERSIONS:
            raise ValueError(f"version must be one of {codec.VERSIONS}, got {self.version!r}")
        if self.mode not in MODES:
            raise ValueError(f"mode must be one of {MODES}, got {self.mode!r}")
        epoch = self.clock_epoch_us
        if isinstance(epoch, bool) or not isinstance(epoch, int) or not 0 <= epoch < 1 << 63:
            raise ValueError(f"clock_epoch_us must be an int of µs since 1970 >= 0, got {epoch!r}")
        ticks = self.sample_period_s / 0.004
        if self.sample_period_s <= 0 or abs(ticks - round(ticks)) > 1e-9:
            raise ValueError(f"sample_period_s must be a multiple of 0.004 s, got "
                             f"{self.sample_period_s}")
        if not (math.isfinite(self.comm_timeout_s) and self.comm_timeout_s > 0):
            raise ValueError(f"comm_timeout_s must be > 0, got {self.comm_timeout_s}")
        again = self.restart_after_s
        if again is not None and not (math.isfinite(again) and again >= 0):
            raise ValueError(f"restart_after_s must be None or >= 0, got {again}")


class EgmControllerModel:
    """One emulated controller's EGM state. Not thread-safe: the server owns it.

    Args:
        config: controller settings.
        physics: shared cell physics; its pose is the start pose and receives every
            reached pose.
        t_s: simulated time of power-up.
        motion: the arm's motion model (default: :class:`LagServo` from ``config.servo``).
    """

    def __init__(
        self,
        config: EgmControllerConfig,
        physics: CellPhysics,
        t_s: float = 0.0,
        motion: MotionModel | None = None,
    ) -> None:
        self.config = config
        self.physics = physics
        self.motion: MotionModel = motion or LagServo(config.servo, physics.pose, t_s)
        self.pose = physics.pose
        self.planned = physics.pose
        """The planned pose in effect (the latest EgmSensor read)."""
        self.planned_joints = self._joints(physics.pose, ())
        """The planned axes in effect, degrees."""
        self._joints_known: tuple[float, ...] = self.planned_joints
        self._joints_to_find: list[Pose] = []
        """Reached poses whose axes are not found yet, in order (:attr:`_feedback_joints`)."""
        self._feedback_joints_pose = physics.pose
        self.mci = codec.MciState.RUNNING
        self.rapid = codec.RapidState.RUNNING
        self.sessions = 1
        self.targets_read = 0
        """EgmSensor planned poses taken (not counting ignored or refused ones)."""
        self.ignored = 0
        """EgmSensor datagrams ignored (unreadable, or guidance not running)."""
        self.wrong_mode = 0
        """EgmSensor datagrams with position data only for the other mode (reference kept)."""
        self._seqno = 0
        self._built = 0  # EgmRobot messages built (a deferred force is of the latest only)
        self._published: Pose | None = None  # the pose last written to the physics
        self._last_read_s = t_s
        self._timed_out_s: float | None = None
        """When the last CommTimeout ended guidance, s (None: guided, or restarted since)."""
        self._last_pose_s = (t_s, physics.pose)
        self._speed_from: tuple[float, Pose] | None = None
        """(time s, pose) the latest cycle started from, its speed not found yet (``_speed``)."""
        self._speed_found = 0.0
        self._checks = TargetChecks(config.arm, config.workspace_min_mm, config.workspace_max_mm)
        self._follow: Callable[[Pose, float], Pose | None] | None = getattr(
            self.motion, "follow", None)
        self._resting: Callable[[Pose], Pose | None] | None = getattr(
            self.motion, "resting", None)
        """The motion model's ``resting`` and ``rest_through`` (:meth:`rest_pose`), if any."""
        self._rest_through: Callable[[Sequence[float]], None] | None = getattr(
            self.motion, "rest_through", None)
        self._follow_keys: Callable[..., Any] | None = getattr(self.motion, "follow_keys", None)
        self._command_keys: Callable[..., Any] | None = getattr(self.motion, "command_keys", None)
        self._can_run: Callable[[], bool] | None = getattr(self.motion, "can_run", None)
        self._take_run: Callable[[list[Any]], None] | None = getattr(self.motion, "take_run", None)
        """The motion model's ``follow_keys``, ``command_keys``, ``can_run`` and ``take_run``
        (:meth:`run_start`)."""
        self._run: list[tuple[Any, ...]] = []
        self._run_holds = True
        """The motion model's ``follow(target, t_s)`` (:meth:`follow_cycle`), if it has one."""

    @property
    def running(self) -> bool:
        """True while EGM guidance runs (MCI_RUNNING)."""
        return self.mci is codec.MciState.RUNNING

    def restart_due(self, t_s: float) -> bool:
        """True when the RAPID program re-opens guidance at ``t_s`` after a CommTimeout."""
        again, since = self.config.restart_after_s, self._timed_out_s
        return again is not None and since is not None and t_s - since >= again - 1e-9

    def restart(self, t_s: float) -> None:
        """Start a new session at ``t_s`` (seqno 0), holding the robot where it is."""
        self._timed_out_s = None
        self._hold(t_s)
        self.mci, self.rapid = codec.MciState.RUNNING, codec.RapidState.RUNNING
        self._seqno = 0
        self._last_read_s = t_s
        self.sessions += 1
        log.info("EGM session %d starts at %.3f s", self.sessions, t_s)

    def _hold(self, t_s: float) -> None:
        self.pose = self.motion.advance_to(t_s)
        hold = getattr(self.motion, "hold", None)
        if hold is not None:
            hold(t_s)
        else:
            self.motion.command(self.pose, t_s - self.config.servo.control_lag_s)
        self.planned = self.pose
        self.planned_joints = self._joints(self.pose, self.planned_joints)

    def _joints(self, pose: Pose, fallback: tuple[float, ...]) -> tuple[float, ...]:
        """The arm's axes at ``pose`` (deg); ``fallback`` if the arm cannot reach it."""
        joints = joint_angles_deg(self.config.arm, pose)
        return fallback if joints is None else joints

    def apply_sensor(self, datagram: carried.Datagram, t_s: float) -> None:
        """Read one EgmSensor at the cycle of time ``t_s``."""
        if not self.running:
            self.ignored += 1
            return
        message = carried.received_sensor(datagram, self.config.version)
        if message is None:
            try:
                message = codec.decode_sensor(bytes(datagram), self.config.version)
            except ProtocolError as exc:
                log.info("EgmSensor ignored: %s", exc)
                self.ignored += 1
                return
        self._last_read_s = t_s
        if self.config.mode == "joint":
            self._apply_joints(message, t_s)
            return
        target = message.planned
        if target is None:
            if message.planned_joints_deg:
                self._count_wrong_mode(t_s, "planned.joints", "\\Pose")
            return  # no position data: the controller keeps the last planned pose
        self._plan(target, message.speed_ref, t_s)

    def _plan(self, target: Pose, speed_ref: tuple[float, ...] | None, t_s: float) -> None:
        """Pose mode: check ``target`` and command it (a motion error if refused)."""
        refusal, joints = self._checks.checked(target)
        if refusal:
            self._motion_error(t_s, refusal)
            return
        self.planned = target
        self.planned_joints = self.planned_joints if joints is None else joints
        tau = self.config.servo.time_constant_s
        self.motion.command(feed_forward_pose(target, speed_ref, tau), t_s)
        self.targets_read += 1

    def _apply_joints(self, message: codec.SensorMessage, t_s: float) -> None:
        """Joint mode: follow planned.joints (deg) through the arm's forward kinematics."""
        joints = message.planned_joints_deg
        if not joints:
            if message.planned is not None:
                self._count_wrong_mode(t_s, "planned.cartesian", "\\Joint")
            return
        refusal = arm_joints.limit_violation(self.config.arm, joints)
        target = None
        if refusal is None:
            target = arm_joints.tool_pose(self.config.arm, joints)
            refusal = self._checks.refusal_and_joints(target)[0]
        if refusal or target is None:
            self._motion_error(t_s, refusal or "unreachable joints")
            return
        speed = message.speed_ref_joints_deg_s
        commanded = target
        if speed is not None and len(speed) == 6 and all(math.isfinite(v) for v in speed):
            tau = self.config.servo.time_constant_s
            commanded = arm_joints.tool_pose(
                self.config.arm, tuple(j + v * tau for j, v in zip(joints, speed, strict=True))
            )
        self.planned = target
        self.planned_joints = tuple(float(j) for j in joints)
        self.motion.command(commanded, t_s)
        self.targets_read += 1

    def _motion_error(self, t_s: float, reason: str) -> None:
        log.warning("EGM motion error at %.3f s: %s", t_s, reason)
        self._hold(t_s)
        self.mci = codec.MciState.ERROR

    def _count_wrong_mode(self, t_s: float, field_name: str, setup: str) -> None:
        self.wrong_mode += 1
        if self.wrong_mode == 1:
            log.warning(
                "EgmSensor at %.3f s carries only %s, which EGMSetupUC %s does not read: the "
                "controller keeps its latest reference (counted in wrong_mode)",
                t_s, field_name, setup,
            )

    def robot_datagram(self, t_s: float) -> bytes:
        """Advance to the cycle at ``t_s`` and return its EgmRobot datagram."""
        return codec.encode_robot(self.robot_message(t_s), self.config.version)

    def robot_carried(
        self, t_s: float, defer_force: bool = False, moved: bool = False
    ) -> carried.Carried:
        """:meth:`robot_datagram` not encoded yet (the in-process route).

        ``defer_force``: the measured force is left out and filled in when the
        datagram is finished (``Carried.finish``), which must happen before the
        cell's clock moves on (else ``RuntimeError``): the emulated lockstep
        cell's driver finishes only the message a wait ends on, so the true
        wrench (a pure function of the cell's state at this cycle) is not
        computed for the hundreds of cycles no one reads it of. The
        finished message and its bytes are those of ``defer_force=False``.
        ``moved``: the cell is at the cycle already (:meth:`follow_at` ran).
        """
        version = self.config.version
        build = self._message if moved else self.robot_message
        if not (defer_force and self.config.send_measured_force):
            return carried.carry_robot(build(t_s), version)
        message = build(t_s, with_force=False)
        datagram = carried.carry_robot(message, version)
        clock = self.physics.clock
        now_s, built = clock.now_s, self._built

        def finish() -> codec.RobotMessage:
            if clock.now_s != now_s or self._built != built:
                raise RuntimeError("an EgmRobot's deferred measured force was asked after the "
                                   "cell moved on: finish it before the next cycle or read")
            return replace(message, measured_force=self._measured_force(),
                           fc_active=self.config.force_control_active)

        datagram.pending = finish
        return datagram

    def _measured_force(self) -> tuple[float, ...]:
        """The physics' true wrench as the controller's sensor force (N, N·m)."""
        return tuple(self.physics.true_wrench().tolist())  # the six float64 as Python floats

    def robot_message(self, t_s: float, with_force: bool = True) -> codec.RobotMessage:
        """Advance to the cycle at ``t_s`` and return its EgmRobot as sent.

        ``with_force=False`` leaves the measured force out (:meth:`robot_carried`).
        """
        self._move_to(t_s)
        return self._message(t_s, with_force)

    def _move_to(self, t_s: float) -> None:
        """The cycle at ``t_s`` up to its EgmRobot: timeout, the arm, the axes (what it sends)."""
        if self.running and t_s - self._last_read_s >= self.config.comm_timeout_s - 1e-9:
            log.warning("EGM comm timeout at %.3f s: no EgmSensor for %.3f s", t_s,
                        t_s - self._last_read_s)
            self._hold(t_s)
            self.mci, self.rapid = codec.MciState.STOPPED, codec.RapidState.STOPPED
            self._timed_out_s = t_s
        self._moved(t_s, self.motion.advance_to(t_s))

    def _moved(self, t_s: float, pose: Pose) -> None:
        """The rest of :meth:`_move_to` once the arm reached ``pose`` at ``t_s``."""
        published = self._published
        if (pose is not published and pose != published) or not self.physics.holds(published):
            self.physics.set_pose(pose)  # else at rest where it was published (and observed)
            self._published = pose
        self._reached(t_s, pose)

    def _reached(self, t_s: float, pose: Pose) -> None:
        """The model's own record of ``pose`` reached at ``t_s``: the speed, the axes to find."""
        self.pose = pose
        self._speed_from = self._last_pose_s  # the speed is found when an EgmRobot reports it
        self._last_pose_s = (t_s, pose)
        joints_pose = self._feedback_joints_pose
        if pose is not joints_pose and pose != joints_pose:  # at rest the axes stay
            self._joints_to_find.append(pose)  # found when an EgmRobot reports them
            self._feedback_joints_pose = pose

    @property
    def _speed(self) -> float:
        """The TCP speed over the latest cycle, mm/s (utilizationRate): found when asked.

        The distance from the pose the cycle started from to the one it reached over
        the cycle's time, as each cycle found it before (only the latest is read).
        """
        start = self._speed_from
        if start is not None:
            (t0, p0), (t_s, pose) = start, self._last_pose_s
            self._speed_found = _distance_mm(pose, p0) / max(t_s - t0, 1e-9)
            self._speed_from = None
        return self._speed_found

    @property
    def _feedback_joints(self) -> tuple[float, ...]:
        """The reported axes (deg): the arm's at the latest reached pose it can reach.

        Each reached pose's axes replace the last ones unless the arm cannot
        reach it (:meth:`_joints`); found only when asked, from the latest pose
        back: the first reachable one is what the cycles one by one would hold.
        """
        poses = self._joints_to_find
        if poses:
            arm = self.config.arm
            for pose in reversed(poses):
                joints = joint_angles_deg(arm, pose)
                if joints is not None:
                    self._joints_known = joints
                    break
            poses.clear()
        return self._joints_known

    @_feedback_joints.setter
    def _feedback_joints(self, joints: tuple[float, ...]) -> None:
        self._joints_known = joints
        self._joints_to_find.clear()

    def _message(self, t_s: float, with_force: bool = True) -> codec.RobotMessage:
        """The EgmRobot of the cycle at ``t_s`` once :meth:`_move_to` ran (seqno +1)."""
        force = None
        if self.config.send_measured_force and with_force:
            force = self._measured_force()
        gap = _distance_mm(self.pose, self.planned)
        speed = self._speed
        tm_ms, time_us = self.stamps(t_s)
        message = codec.RobotMessage(
            seqno=self._seqno,
            tm_ms=tm_ms,
            feedback=self.pose,
            planned=self.planned,
            joints_deg=self._feedback_joints,
            time_us=time_us,
            planned_joints_deg=self.planned_joints,
            planned_time_us=time_us + round(self.config.servo.control_lag_s * 1e6),
            motor=codec.MotorState.ON,
            mci=self.mci,
            rapid=self.rapid,
            convergence_met=gap <= CONVERGENCE_MM,
            utilization_pct=min(100.0, 100.0 * speed / self.config.max_speed_mm_s),
            measured_force=force,
            fc_active=self.config.force_control_active if force is not None else None,
        )
        self._seqno = (self._seqno + 1) & 0xFFFFFFFF
        self._built += 1
        return message

    def stamps(self, t_s: float) -> tuple[int, int]:
        """The EgmRobot's header.tm (ms) and feedBack.time (µs since 1970) of a cycle at ``t_s``."""
        return round(t_s * 1000), self.config.clock_epoch_us + round(t_s * 1e6)

    def stamps_at(self, times_s: Sequence[float]) -> list[tuple[int, int]]:
        """:meth:`stamps` of each of ``times_s``, in order."""
        return [self.stamps(t_s) for t_s in times_s]

    # -- cycles that only follow (the in-process route's jump: CycleLoop.rest) --------------

    def readable(self, datagram: carried.Datagram) -> Pose | None:
        """The planned pose of ``datagram`` if a jump may read it (:meth:`read_planned`), else None.

        So when guidance runs in pose mode and ``datagram`` is carried and
        plans a pose with no speedRef: reading it is :meth:`read_planned`.
        """
        message = carried.received_sensor(datagram, self.config.version)
        if (message is None or message.planned is None or message.speed_ref is not None
                or self.mci is not codec.MciState.RUNNING
                or self.rapid is not codec.RapidState.RUNNING or self._timed_out_s is not None
                or self.config.mode != "pose"
                or not self.config.comm_timeout_s > self.config.sample_period_s):
            return None
        return message.planned

    def read_planned(self, target: Pose, t_s: float) -> None:
        """The cycle at ``t_s`` reads an EgmSensor planning ``target`` (:meth:`readable`).

        :meth:`apply_sensor` of it: the pose in effect, checked and commanded
        already, is only read again (:meth:`follow_at`'s read); the cycle then
        goes on with :meth:`move_to` (or :meth:`restart`, then :meth:`robot_carried`).
        """
        self._last_read_s = t_s
        commands = getattr(self.motion, "commands", None)
        if ((target is self.planned or target == self.planned) and self._checks.passed(target)
                and commands is not None and not commands(target)):
            self.targets_read += 1
        else:
            self._plan(target, None, t_s)

    def move_to(self, t_s: float) -> Pose:
        """The cell moved to the cycle at ``t_s`` as :meth:`robot_message` does; the pose reached.

        The EgmRobot is then :meth:`robot_carried` with ``moved``, or :meth:`skip`.
        """
        self._move_to(t_s)
        return self.pose

    def follow_cycle(self, target: Pose, t_s: float) -> Pose:
        """:meth:`read_planned` of ``target`` then :meth:`move_to` ``t_s``, in one call.

        Where ``target`` is the pose in effect, checked, passed and commanded (the
        same objects: a wait at rest reads the ramp's last pose every cycle), the
        read is the read time and the count, and the motion model follows
        (``follow``) without the checks' and the command's look-ups; the
        CommTimeout check of :meth:`_move_to` cannot fire (the read is at ``t_s``).
        """
        follow, last = self._follow, self._checks.last
        if (follow is not None and target is self.planned and last is not None
                and last[0] is target and last[1] is None):
            pose = follow(target, t_s)
            if pose is not None:
                self._last_read_s = t_s
                self.targets_read += 1
                self._moved(t_s, pose)
                return pose
        self.read_planned(target, t_s)
        self._move_to(t_s)
        return self.pose

    def rest_pose(self, target: Pose) -> Pose | None:
        """The feedback pose of every cycle that reads ``target`` from now on, if they only rest.

        So when :meth:`follow_cycle` of ``target`` takes its short route, the
        arm rests (``resting``: nothing pending, no speed, on its reference)
        and its pose is the one published, with its axes: each such cycle then
        changes only the read time and count, the speed and the sponge's
        relaxation (:meth:`rest_through`), whatever the PC answers meanwhile.
        None: not so (each cycle runs :meth:`follow_cycle`).
        """
        resting, last = self._resting, self._checks.last
        if (resting is None or self._rest_through is None or target is not self.planned
                or last is None or last[0] is not target or last[1] is not None
                or self.mci is not codec.MciState.RUNNING):
            return None
        pose = resting(target)
        if (pose is None or pose is not self.pose or pose is not self._published
                or pose is not self._feedback_joints_pose or not self.physics.holds(pose)):
            return None
        return pose

    def rest_through(self, times_s: Sequence[float]) -> None:
        """:meth:`follow_cycle` of the planned pose at each of ``times_s``, ascending (one or more).

        :meth:`rest_pose` of it must have held: the arm rests, so the cycles are
        the sponge's ticks and the model's read time, count and speed.
        """
        if self._rest_through is None or not times_s:
            raise RuntimeError("rest_through needs a resting motion model and a cycle")
        self._rest_through(times_s)
        pose, t_s = self.pose, times_s[-1]
        self._last_read_s = t_s
        self.targets_read += len(times_s)
        # as _reached: the last cycle's speed
        self._speed_from = self._last_pose_s if len(times_s) == 1 else (times_s[-2], pose)
        self._last_pose_s = (t_s, pose)

    def run_start(self) -> bool:
        """Whether the cycles from now may run as a run (:meth:`run_cycle`, then :meth:`run_end`).

        So when guidance runs, the pose published is the one the cell holds, and the
        motion model can take the arm's ticks alone and the cell's side at the end
        (``can_run``). :meth:`run_end` must follow the run's cycles.
        """
        return (self._follow_keys is not None and self._command_keys is not None
                and self._can_run is not None and self.mci is codec.MciState.RUNNING
                and self._published is not None and self.physics.holds(self._published)
                and self._can_run())

    def run_cycle(self, t_s: float, target: Pose) -> tuple[Pose, bool] | None:
        """:meth:`follow_cycle` of ``target`` at ``t_s`` in a run; the pose and if the arm rests.

        The arm's ticks run now; the cell's side of them, and of publishing the pose
        (:meth:`_moved`'s ``set_pose``), waits for :meth:`run_end`: nothing reads the cell
        meanwhile. The model's own state is :meth:`follow_cycle`'s. ``target`` is the
        pose in effect (its short route) or a new planned pose its check passes (read,
        checked and commanded as :meth:`_plan` does). None, nothing done, for any other
        cycle (a refusal, a pose equal to the one in effect but another object): it runs
        one by one.
        """
        last = self._checks.last
        if target is self.planned:
            if last is None or last[0] is not target or last[1] is not None:
                return None
            assert self._follow_keys is not None
            ticked = self._follow_keys(target, t_s)
            if ticked is None:
                return None
        else:
            if target == self.planned:
                return None
            refusal, joints = self._checks.checked(target)
            if refusal:
                return None
            self.planned = target
            if joints is not None:
                self.planned_joints = joints
            assert self._command_keys is not None  # feed_forward_pose without speedRef: target
            ticked = self._command_keys(target, t_s)
        keys, rest, key, pose, moved = ticked
        if moved:
            self._run_holds = False  # a tick moved the tool: the cell's pose is read anew
        published, seen = self._published, None
        if not self._run_holds or (pose is not published and pose != published):
            seen = self._published = pose
            self._run_holds = True
        self._run.append((keys, rest, key, seen))
        self._last_read_s = t_s
        self.targets_read += 1
        self._reached(t_s, pose)
        return pose, rest != 0 or not keys

    def run_end(self) -> None:
        """The cell's side of the run's cycles (idempotent: a run with no cycle does nothing)."""
        run, self._run = self._run, []
        self._run_holds = True
        if run:
            assert self._take_run is not None
            self._take_run(run)

    def cycles_to_wrap(self) -> int:
        """How many EgmRobots may be built before :meth:`wraps_next` holds (0: it holds now)."""
        return 0xFFFFFFFF - self._seqno

    def wraps(self) -> bool:
        """Whether the next EgmRobot's seqno is 0 (a wrap: it looks like a new session)."""
        return self._seqno == 0

    def wraps_next(self) -> bool:
        """Whether the EgmRobot after the next has seqno 0."""
        return self._seqno == 0xFFFFFFFF

    def can_follow(self, datagram: carried.Datagram) -> bool:
        """Whether each cycle that reads the EgmSensor ``datagram`` only follows the arm.

        So when guidance runs in pose mode and ``datagram`` is carried and
        plans the pose in effect with no speedRef (the same check passed,
        nothing commanded): reading it changes only the read time and count,
        and the cycle is :meth:`follow_at`, then its EgmRobot.
        """
        planned = self.readable(datagram)
        if planned is None:
            return False
        commands = getattr(self.motion, "commands", None)
        return (planned == self.planned and self._checks.passed(planned)
                and commands is not None and not commands(planned))

    def follow_at(self, t_s: float) -> Pose | None:
        """The cycle at ``t_s`` as :meth:`can_follow` allows, up to its EgmRobot; its pose.

        Reads the EgmSensor again and moves the cell as :meth:`robot_message`
        does; the EgmRobot is then :meth:`robot_carried` with ``moved`` (or
        :meth:`skip` if it is not needed). None, running nothing, when the
        cycle's seqno would be 0 (a wrap looks like a new session: that cycle
        runs in full).
        """
        if self._seqno == 0:
            return None
        self._last_read_s = t_s  # the EgmSensor read: the planned pose in effect again
        self.targets_read += 1
        self._move_to(t_s)
        return self.pose

    def skip(self, cycles: int = 1) -> None:
        """Count the EgmRobots of ``cycles`` cycles run up to them as built (no one reads them)."""
        self._seqno = (self._seqno + cycles) & 0xFFFFFFFF
        self._built += cycles

    # -- checkpoint -------------------------------------------------------------------------

    def state_dict(self) -> dict[str, Any]:
        """The session's state (JSON-able); the motion model saves its own."""
        t0, p0 = self._last_pose_s
        return {
            "pose": _pose_list(self.pose),
            "planned": _pose_list(self.planned),
            "planned_joints": list(self.planned_joints),
            "feedback_joints": list(self._feedback_joints),
            "wrong_mode": self.wrong_mode,
            "mci": self.mci.name,
            "rapid": self.rapid.name,
            "sessions": self.sessions,
            "targets_read": self.targets_read,
            "ignored": self.ignored,
            "seqno": self._seqno,
            "last_read_s": self._last_read_s,
            "last_pose": [t0, *_pose_list(p0)],
        } | ({} if self._timed_out_s is None else {"timed_out_s": self._timed_out_s})

    def load_state_dict(self, state: dict[str, Any]) -> None:
        """Restore :meth:`state_dict`."""
        self.pose = _list_pose(state["pose"])
        self.planned = _list_pose(state["planned"])
        self.planned_joints = tuple(float(j) for j in state.get(
            "planned_joints", self._joints(self.planned, self.planned_joints)))
        self._feedback_joints = tuple(float(j) for j in state.get(
            "feedback_joints", self._joints(self.pose, self._feedback_joints)))
        self._feedback_joints_pose = self.pose
        self.wrong_mode = int(state.get("wrong_mode", 0))
        self.mci = codec.MciState[state["mci"]]
        self.rapid = codec.RapidState[state["rapid"]]
        self.sessions = int(state["sessions"])
        self.targets_read = int(state["targets_read"])
        self.ignored = int(state["ignored"])
        timed_out = state.get("timed_out_s")
        self._timed_out_s = None if timed_out is None else float(timed_out)
        self._seqno = int(state["seqno"])
        self._last_read_s = float(state["last_read_s"])
        self._published = None  # the physics is restored on its own
        last = state["last_pose"]
        self._speed_found = self._speed  # (not saved: the speed found before stays, as it did)
        self._last_pose_s = (float(last[0]), _list_pose(last[1:]))


def _distance_mm(a: Pose, b: Pose) -> float:
    """Distance |a - b| of two positions, mm, without arrays (a cycle's hot path).

    The float operations of ``numpy.linalg.norm`` of the difference: the sum of
    the three squares in order, then its square root.
    """
    dx, dy, dz = a.x_mm - b.x_mm, a.y_mm - b.y_mm, a.z_mm - b.z_mm
    return math.sqrt(dx * dx + dy * dy + dz * dz)


def _pose_list(pose: Pose) -> list[float]:
    return [pose.x_mm, pose.y_mm, pose.z_mm, *pose.quaternion]


def _list_pose(values: list[float]) -> Pose:
    x, y, z, w, qx, qy, qz = (float(v) for v in values[:7])
    return Pose(x, y, z, (w, qx, qy, qz))
