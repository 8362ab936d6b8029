"""The emulated arm shared by every robot kind: geometry, limits, kinematics, motion settings.

The arm is a simplified six-axis arm in the spirit of the IRB 2000 (not its
exact geometry): a base joint, a two-link planar shoulder/elbow, and a
spherical wrist. Positions are of the tool centre point in the base frame.

==========  ========================================================  ============
joint       meaning                                                   default range
==========  ========================================================  ============
J1          base yaw, ``atan2(y, x)``                                 -170..170 deg
J2          upper arm from vertical, positive leaning out             -70..110 deg
J3          elbow, relative to the upper arm; 0 is stretched out     -165..-5 deg
J4, J5, J6  wrist: Z-Y-Z Euler angles of the tool orientation         J5 0..180 deg
==========  ========================================================  ============

A target is refused (and the robot does not move) when it lies outside the
workspace box, is out of reach of the two links, breaks a joint range, or its
quaternion is not unit length (within 1e-3).

How the tool moves in time (speed and acceleration limits, start delay,
servo lag, in-position band) is the shared physics' :class:`ArmMotion`; the
defaults and their sources are in :mod:`forcelearn.emulators.physics.arm_motion`.
``instant = True`` reaches every target the moment it is commanded (the
"ideal" profile, today's studies' fast path).
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass, field

import numpy as np

from forcelearn.devices import TOOL_DOWN as TOOL_DOWN  # re-exported: the home pose's
from forcelearn.devices import Pose
from forcelearn.emulators.physics.arm_motion import MotionParams

QUATERNION_TOLERANCE = 1e-3

HOME = Pose(900.0, 0.0, 600.0, TOOL_DOWN)
"""Default power-up pose: 900 mm out, 600 mm up, tool down."""


@dataclass(frozen=True)
class ArmConfig:
    """Geometry, limits and servo settings of the emulated arm (mm, deg, s)."""

    home: Pose = HOME
    """Pose at power-up; written into the shared physics when the emulator starts."""
    workspace_min_mm: tuple[float, float, float] = (300.0, -800.0, -200.0)
    workspace_max_mm: tuple[float, float, float] = (1500.0, 800.0, 1400.0)
    shoulder_height_mm: float = 750.0
    upper_arm_mm: float = 710.0
    forearm_mm: float = 850.0
    joint_limits_deg: tuple[tuple[float, float], ...] = field(
        default=((-170, 170), (-70, 110), (-165, -5), (-180, 180), (0, 180), (-180, 180))
    )
    max_speed_mm_s: float = 1000.0
    default_speed_mm_s: float = 100.0
    """TCP speed of moves until SET_SPEED changes it."""
    accel_mm_s2: float = 1000.0
    start_delay_s: float = 0.05
    """Time from accepting a move to the start of motion (path planning)."""
    lag_s: float = 0.03
    """Servo lag: first-order time constant of the tool behind the planned path."""
    in_position_mm: float = 0.1
    rotation_speed_deg_s: float = 60.0
    tick_s: float = 0.004
    """The controller's interpolation period."""
    instant: bool = False
    """Reach every target the moment it is accepted (the "ideal" profile)."""
    reply_latency_s: float = 0.005
    """Time from the end of a request on the wire to the start of the reply (assumption)."""

    def __post_init__(self) -> None:
        for axis in range(3):
            if self.workspace_min_mm[axis] >= self.workspace_max_mm[axis]:
                raise ValueError(f"workspace_min_mm[{axis}] must be below workspace_max_mm")
        if not 0 < self.default_speed_mm_s <= self.max_speed_mm_s:
            raise ValueError("need 0 < default_speed_mm_s <= max_speed_mm_s")
        if not (math.isfinite(self.reply_latency_s) and self.reply_latency_s >= 0):
            raise ValueError("reply_latency_s must be >= 0")
        if len(self.joint_limits_deg) != 6:
            raise ValueError("joint_limits_deg needs six (low, high) pairs")
        for name in ("upper_arm_mm", "forearm_mm"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0):
                raise ValueError(f"{name} must be a finite length > 0 mm, got {value!r}")
        if not math.isfinite(self.shoulder_height_mm):
            raise ValueError(f"shoulder_height_mm must be finite, got {self.shoulder_height_mm!r}")
        self.motion_params()  # validates the motion settings

    def motion_params(self) -> MotionParams:
        """The shared physics' motion settings of this arm."""
        return MotionParams(
            speed_mm_s=self.default_speed_mm_s,
            accel_mm_s2=self.accel_mm_s2,
            start_delay_s=self.start_delay_s,
            lag_s=self.lag_s,
            in_position_mm=self.in_position_mm,
            rotation_speed_deg_s=self.rotation_speed_deg_s,
            tick_s=self.tick_s,
            instant=self.instant,
        )


def joint_angles_deg(
    config: ArmConfig, pose: Pose
) -> tuple[float, float, float, float, float, float] | None:
    """Return (J1..J6) in degrees for ``pose``, or None if the links cannot reach it.

    Plain floats (no numpy): the EGM emulator computes it twice per 4 ms cycle.
    """
    x, y, z = pose.x_mm, pose.y_mm, pose.z_mm
    r, h = math.hypot(x, y), z - config.shoulder_height_mm
    a, b = config.upper_arm_mm, config.forearm_mm
    cos_elbow = (r * r + h * h - a * a - b * b) / (2 * a * b)
    if not -1.0 <= cos_elbow <= 1.0:
        return None
    j3 = -math.acos(cos_elbow)  # elbow up
    upper_from_horizontal = math.atan2(h, r) - math.atan2(b * math.sin(j3), a + b * math.cos(j3))
    j4, j5, j6 = _zyz_euler(pose.quaternion)
    return (
        math.degrees(math.atan2(y, x)), math.degrees(math.pi / 2 - upper_from_horizontal),
        math.degrees(j3), j4, j5, j6,
    )


@functools.lru_cache(maxsize=1024)
def _zyz_euler(q: tuple[float, float, float, float]) -> tuple[float, float, float]:
    """Z-Y-Z Euler angles (deg) of a quaternion (w, x, y, z), normalised; J4 = 0 at J5 0 or 180."""
    norm = math.sqrt(sum(c * c for c in q))
    w, x, y, z = (c / norm for c in q)
    r22 = 1 - 2 * (x * x + y * y)
    beta = math.acos(max(-1.0, min(1.0, r22)))
    if math.sin(beta) < 1e-9:
        r10, r11 = 2 * (x * y + w * z), 1 - 2 * (x * x + z * z)
        return 0.0, math.degrees(beta), math.degrees(math.atan2(r10, r11))
    r02, r12 = 2 * (x * z + w * y), 2 * (y * z - w * x)
    r20, r21 = 2 * (x * z - w * y), 2 * (y * z + w * x)
    return (
        math.degrees(math.atan2(r12, r02)), math.degrees(beta),
        math.degrees(math.atan2(r21, -r20)),
    )


def check_target(config: ArmConfig, pose: Pose) -> tuple[str, str] | None:
    """Return (kind, reason) if ``pose`` must be refused, else None.

    ``kind`` is "orientation", "workspace" or "joint".
    """
    norm = math.sqrt(sum(c * c for c in pose.quaternion))
    if not all(math.isfinite(c) for c in (pose.x_mm, pose.y_mm, pose.z_mm, norm)):
        return "workspace", "target has a non-finite coordinate"
    if abs(norm - 1.0) > QUATERNION_TOLERANCE:
        return "orientation", f"quaternion norm {norm:.4f} is not 1"
    position = (float(pose.x_mm), float(pose.y_mm), float(pose.z_mm))  # (no arrays: every move)
    if not all(lo <= c <= hi for c, lo, hi in zip(
            position, config.workspace_min_mm, config.workspace_max_mm, strict=True)):
        return "workspace", f"target {np.round(position, 3).tolist()} mm is outside the workspace"
    joints = joint_angles_deg(config, pose)
    if joints is None:
        return "joint", "target is out of reach of the arm"
    for number, (angle, (lo, hi)) in enumerate(zip(joints, config.joint_limits_deg, strict=True)):
        if not lo - 1e-9 <= angle <= hi + 1e-9:
            return "joint", f"J{number + 1} would be {angle:.1f} deg, outside {lo}..{hi}"
    return None
