"""The six joint angles an EGM controller reports, from the emulated cell's one arm (pure).

A real controller sends ``feedBack.joints`` and ``planned.joints`` in every
EgmRobot: the measured and the planned angles of the robot's six axes, in
degrees "relative to the calibration position of each axis" (manual
3HAC073318 RW7, p.30 and p.38). The emulated cell has one arm for both robot
links: :class:`~forcelearn.emulators.physics.arm.ArmConfig`,
a simplified six-axis arm in the spirit of the IRB 2000 (the computer-link
emulator reports the same joints). Its geometry and limits (defaults):

==========  =====================================================  ==============
joint       meaning                                                range (deg)
==========  =====================================================  ==============
J1          base yaw, ``atan2(y, x)``                              -170..170
J2          upper arm from vertical, positive leaning out          -70..110
J3          elbow, relative to the upper arm, elbow up             -165..-5
J4, J5, J6  wrist: Z-Y-Z Euler angles of the tool orientation      -180..180,
                                                                   0..180, -180..180
==========  =====================================================  ==============

Shoulder 750 mm above the base, upper arm 710 mm, forearm 850 mm to the tool
centre point (no separate wrist offset). Inverse kinematics
(``physics.arm.joint_angles_deg``, the computer-link
emulator's own: one arm, one computation) takes the elbow-up branch and J4 = 0 at a wrist
singularity (J5 = 0 or 180); forward kinematics (:func:`tool_pose`) is its
inverse. A tool pointing straight down (the cell's home) is J5 = 180 deg,
such a singularity: J4 = 0, and J6 carries the tool's turn about the
vertical (180 deg at the home). This is not the geometry of a real IRB: a real controller reports
its own robot's axes, and a program that reads joints must use the joints of
the real robot, not these numbers.

Units: mm, degrees; poses of the tool centre point in the robot base frame,
quaternion (w, x, y, z).
"""

from __future__ import annotations

import math

from forcelearn.devices import Pose, multiply_quaternions
from forcelearn.emulators.physics.arm import ArmConfig


def limit_violation(arm: ArmConfig, joints_deg: tuple[float, ...]) -> str | None:
    """Return why ``joints_deg`` break the axis ranges (or are not 6 finite angles), else None."""
    if len(joints_deg) != 6 or not all(math.isfinite(j) for j in joints_deg):
        return f"need 6 finite joint angles in degrees, got {list(joints_deg)}"
    for number, (angle, (low, high)) in enumerate(
        zip(joints_deg, arm.joint_limits_deg, strict=True), start=1
    ):
        if not low - 1e-9 <= angle <= high + 1e-9:
            return f"J{number} = {angle:.3f} deg is outside its range {low}..{high} deg"
    return None


def _axis_quaternion(axis: int, angle_deg: float) -> tuple[float, float, float, float]:
    half = math.radians(angle_deg) / 2.0
    q = [math.cos(half), 0.0, 0.0, 0.0]
    q[1 + axis] = math.sin(half)
    return q[0], q[1], q[2], q[3]


def tool_pose(arm: ArmConfig, joints_deg: tuple[float, ...]) -> Pose:
    """Return the tool pose (mm, quaternion) of J1..J6 in degrees (forward kinematics).

    Raises ``ValueError`` unless there are six finite angles.
    """
    if len(joints_deg) != 6 or not all(math.isfinite(j) for j in joints_deg):
        raise ValueError(f"need 6 finite joint angles in degrees, got {list(joints_deg)}")
    j1, j2, j3 = (math.radians(j) for j in joints_deg[:3])
    upper = math.pi / 2 - j2  # the upper arm's angle above the horizontal
    a, b = arm.upper_arm_mm, arm.forearm_mm
    reach = a * math.cos(upper) + b * math.cos(upper + j3)
    height = a * math.sin(upper) + b * math.sin(upper + j3)
    q = multiply_quaternions(_axis_quaternion(2, joints_deg[3]), _axis_quaternion(1, joints_deg[4]))
    q = multiply_quaternions(q, _axis_quaternion(2, joints_deg[5]))
    return Pose(
        reach * math.cos(j1), reach * math.sin(j1), arm.shoulder_height_mm + height, q
    )
