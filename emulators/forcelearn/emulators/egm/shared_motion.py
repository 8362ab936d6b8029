"""The EGM emulator on the cell's shared arm: :class:`PhysicsMotion` behind the servo seam.

In an emulated cell the sponge, the sensor and the robot must see one arm:
``CellPhysics.motion``, an :class:`~forcelearn.emulators.physics.arm_motion.ArmMotion`
advanced on its tick grid (which also lets the sponge relax). The EGM
controller model asks its motion model only for ``command(target, t_s)``,
``advance_to(t_s) -> Pose`` and ``hold(t_s)`` (:class:`~.servo.MotionModel`);
:class:`PhysicsMotion` answers them with the shared arm, so the EGM emulator
replaces its private :class:`~.servo.LagServo` with it.

How EGM's servo maps onto the arm (:func:`egm_motion_params`)
-------------------------------------------------------------
=======================  ===============================  =====================================
ArmMotion parameter      EGM value                        why
=======================  ===============================  =====================================
``start_delay_s``        ``control_lag_s`` (20 ms)        EGM's control lag: a planned pose
                                                          starts to act this long after the
                                                          controller reads it (manual p.17)
``lag_s``                ``time_constant_s`` (10 ms)      the axis servo's first-order lag
``speed_mm_s``           the arm's ``max_speed_mm_s``     EGM has no path planner: the PC's
                                                          ramp sets the speed, the arm only
                                                          caps it
``accel_mm_s2``          the arm's ``accel_mm_s2``        the same arm as the computer link's
``tick_s``, band         the arm's (4 ms = EGM's cycle)
=======================  ===============================  =====================================

Each planned pose read from an EgmSensor becomes a new segment of the arm
from where its reference is, keeping the speed that points the same way, so
a ramp of small planned steps is followed at the ramp's speed once the arm
has accelerated (the accelerating arm trails a fast ramp by a few mm and
then catches up; :class:`~.servo.LagServo`, which has no acceleration
limit, does not). A repeated planned pose (every cycle at rest) is not
commanded again. Not thread-safe: the emulator's cycle loop owns it, and in
lockstep no other device moves the arm while a cycle runs.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import replace

from forcelearn.devices import Pose
from forcelearn.emulators.egm.servo import ServoParams
from forcelearn.emulators.physics.arm_motion import MotionParams, PoseKey
from forcelearn.emulators.physics.cell import CellPhysics


def egm_motion_params(arm: MotionParams, servo: ServoParams, max_speed_mm_s: float) -> MotionParams:
    """The arm's motion settings under EGM guidance (see the module table)."""
    return replace(
        arm,
        speed_mm_s=max_speed_mm_s,
        start_delay_s=servo.control_lag_s,
        lag_s=servo.time_constant_s,
    )


class PhysicsMotion:
    """:class:`~.servo.MotionModel` over ``physics.motion`` (which must be attached).

    Args:
        physics: the cell's physics with its shared :class:`ArmMotion`.
    """

    def __init__(self, physics: CellPhysics) -> None:
        if physics.motion is None:
            raise ValueError("PhysicsMotion needs physics.motion: attach an ArmMotion first")
        self.physics = physics
        self.motion = physics.motion
        self._last: Pose | None = None

    def command(self, target: Pose, t_s: float) -> None:
        """Plan ``target`` read at ``t_s``; it starts to act after the control lag."""
        if target == self._last:
            return
        self._last = target
        self.physics.advance_to(t_s)
        self.motion.command(target, t_s)

    def commands(self, target: Pose) -> bool:
        """Whether :meth:`command` of ``target`` would command the arm (else it does nothing)."""
        return target != self._last

    def advance_to(self, t_s: float) -> Pose:
        """Move the arm (and let the sponge relax) up to ``t_s``; return the tool pose."""
        self.physics.advance_to(t_s)
        return self.motion.pose

    def follow(self, target: Pose, t_s: float) -> Pose | None:
        """:meth:`advance_to` ``t_s`` if ``target`` is the pose last commanded (the object).

        So when a cycle reads the planned pose in effect again (:meth:`command`
        of it does nothing); None, nothing done, for any other ``target``. An
        arm at rest is jumped without its tick callback (``CellPhysics.rest_to``).
        """
        if target is not self._last:
            return None
        physics = self.physics
        if not (self.motion.resting and physics.rest_to(t_s)):  # (a moving arm: not tried)
            physics.advance_to(t_s)
        return self.motion.pose

    def resting(self, target: Pose) -> Pose | None:
        """The arm's pose if it rests and ``target`` is the pose last commanded (the object).

        Then every :meth:`follow` of ``target`` from now on is a rest of the arm
        (``CellPhysics.rest_to``) and returns this pose; None: not so.
        """
        if target is not self._last or not self.motion.resting or not self.physics.at_rest():
            return None
        return self.motion.pose

    def rest_through(self, times_s: Sequence[float]) -> None:
        """:meth:`follow` of the pose last commanded at each of ``times_s`` (``resting``)."""
        self.physics.rest_through(times_s)

    def follow_keys(
        self, target: Pose, t_s: float
    ) -> tuple[list[PoseKey], int, PoseKey, Pose, bool] | None:
        """:meth:`follow` of ``target`` with the arm's ticks alone (``ArmMotion.advance_keys``).

        Returns the tool keys of the ticks, the ticks jumped at rest, the tool key and
        pose then, and whether a tick moved the tool (a key unlike the one before); the
        cell's side of them is :meth:`take_run`'s. None, nothing done, for another target.
        """
        if target is not self._last:
            return None
        motion = self.motion
        before = motion.tool_key
        keys, rest = motion.advance_keys(t_s)
        return keys, rest, motion.tool_key, motion.pose, _moved(keys, before)

    def command_keys(
        self, target: Pose, t_s: float
    ) -> tuple[list[PoseKey], int, PoseKey, Pose, bool]:
        """:meth:`command` of ``target`` read at ``t_s``, then the arm to ``t_s``, ticks alone.

        As :meth:`follow_keys` (the same return); the arm's ticks to ``t_s`` run before
        the command is taken, as :meth:`command` then :meth:`advance_to` run them.
        """
        motion = self.motion
        before = motion.tool_key
        keys, rest = motion.advance_keys(t_s)
        if target != self._last:  # as command(): a repeated pose is not commanded again
            self._last = target
            motion.command(target, t_s)
        return keys, rest, motion.tool_key, motion.pose, _moved(keys, before)

    def can_run(self) -> bool:
        """Whether :meth:`follow_keys` and :meth:`take_run` may stand for :meth:`follow` now."""
        return self.physics.can_run()

    def take_run(self, cycles: Sequence[tuple[list[PoseKey], int, PoseKey, Pose | None]]) -> None:
        """The cell's side of the :meth:`follow_keys` cycles (``CellPhysics.take_run``)."""
        self.physics.take_run(cycles)

    def hold(self, t_s: float) -> None:
        """Stop where the arm is at ``t_s`` (brake along the present path, drop planned poses)."""
        self.physics.advance_to(t_s)
        self.motion.stop(t_s)
        self._last = None


def _moved(keys: list[PoseKey], before: PoseKey) -> bool:
    """Whether a tick's tool key differs from the key before the ticks (the tool moved)."""
    for key in keys:  # noqa: SIM110 (a loop: any()'s generator costs more, every cycle)
        if key != before:
            return True
    return False
