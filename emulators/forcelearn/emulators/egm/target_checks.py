"""The emulated controller's check of a planned pose: workspace, reach, axis limits (pure).

A real controller stops with a motion error on a planned pose it cannot
follow; :class:`TargetChecks` says why it would (None: it follows it) and
gives the arm's six axes there. The PC sends the same planned pose cycle
after cycle while the arm rests or follows, so the latest answer is kept.
"""

from __future__ import annotations

import math

import numpy as np

from forcelearn.devices import Pose
from forcelearn.emulators.egm import joints as arm_joints
from forcelearn.emulators.physics.arm import ArmConfig, joint_angles_deg

Checked = tuple[str | None, tuple[float, ...] | None]
"""(why the pose is refused, or None; the arm's axes there in degrees, or None if refused)."""


class TargetChecks:
    """The checks of one controller's configuration, with the latest result kept.

    Args:
        arm: the arm (geometry and axis ranges).
        workspace_min_mm / workspace_max_mm: the controller's workspace box, mm.
    """

    def __init__(
        self,
        arm: ArmConfig,
        workspace_min_mm: tuple[float, float, float],
        workspace_max_mm: tuple[float, float, float],
    ) -> None:
        self.arm = arm
        self.low, self.high = workspace_min_mm, workspace_max_mm
        self.last: tuple[Pose, str | None, tuple[float, ...] | None] | None = None
        """The latest pose checked, its refusal and its axes."""
        self._unit_q: tuple[float, ...] | None = None  # the latest quaternion found unit length
        limits = tuple((low - 1e-9, high + 1e-9) for low, high in arm.joint_limits_deg)
        self._limits = limits if len(limits) == 6 and all(
            math.isfinite(v) for pair in limits for v in pair) else None
        """The axis ranges as :func:`~.joints.limit_violation` widens them (finite), or None."""

    def checked(self, target: Pose) -> Checked:
        """:meth:`refusal_and_joints` of ``target``, kept for a repeat."""
        last = self.last
        if last is not None and (last[0] is target or last[0] == target):
            return last[1], last[2]
        refusal, joints = self.refusal_and_joints(target)
        self.last = (target, refusal, joints)
        return refusal, joints

    def passed(self, target: Pose) -> bool:
        """Whether ``target`` is the latest pose checked and was not refused (nothing computed)."""
        last = self.last
        return last is not None and last[1] is None and (last[0] is target or last[0] == target)

    def refusal_and_joints(self, pose: Pose) -> Checked:
        """Why the controller refuses ``pose`` (None: it does not), and the arm's axes there.

        A pose that passes is found so by the same comparisons written out (a
        ramp checks one every 4 ms cycle; a quaternion found unit length is kept);
        a refusal is worded by :meth:`_refusal_and_joints`.
        """
        x, y, z, q = pose.x_mm, pose.y_mm, pose.z_mm, pose.quaternion
        (x0, y0, z0), (x1, y1, z1), limits = self.low, self.high, self._limits
        if (limits is not None and math.isfinite(x) and math.isfinite(y) and math.isfinite(z)
                and x0 <= x <= x1 and y0 <= y <= y1 and z0 <= z <= z1
                and (q is self._unit_q or self._unit(q))):
            joints = joint_angles_deg(self.arm, pose)
            if joints is not None and all(
                    low <= j <= high for j, (low, high) in zip(joints, limits, strict=True)):
                return None, joints
        return self._refusal_and_joints(pose)

    def _unit(self, q: tuple[float, ...]) -> bool:
        """Whether ``q`` has unit length as the check asks (kept as the latest if so)."""
        if abs(math.sqrt(sum(c * c for c in q)) - 1.0) <= 1e-3:
            self._unit_q = q
            return True
        return False

    def _refusal_and_joints(self, pose: Pose) -> Checked:
        """:meth:`refusal_and_joints` step by step, each refusal worded."""
        position = (pose.x_mm, pose.y_mm, pose.z_mm)
        norm = math.sqrt(sum(c * c for c in pose.quaternion))
        if not (all(math.isfinite(c) for c in position) and abs(norm - 1.0) <= 1e-3):
            return f"planned pose {pose} is not finite or its quaternion not unit length", None
        if any(c < lo or c > hi for c, lo, hi in zip(position, self.low, self.high, strict=True)):
            return (f"planned position {np.round(position, 3).tolist()} mm is outside the "
                    "workspace"), None
        joints = joint_angles_deg(self.arm, pose)
        if joints is None:
            return (f"planned position {np.round(position, 3).tolist()} mm is out of the arm's "
                    "reach"), None
        refusal = arm_joints.limit_violation(self.arm, joints)
        return refusal, None if refusal else joints
