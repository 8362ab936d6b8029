"""A planar two-link arm pressing on a circular surface: the simulated cell of paper §4.

Description
-----------
The arm of §4 (l1 = 1 m, l2 = 0.8 m) is commanded by joint angles through a
position servo; the learning controller never sees its dynamics. The servo is
ideal by default (the commanded angles are reached in one control step); an
optional first-order lag reaches only the fraction ``1 - servo_lag`` of the
remaining way per step.

The surface is a rigid disc in front of the arm (radius ``radius_m``) whose
compliance is a linear stiffness of 100 N/m: the normal force is
``stiffness · penetration``, where penetration = radius − |tip − centre| when
positive, and zero out of contact. The tool presses on the disc from outside.

Geometry (defaults, all derived in :class:`ContourGeometry`)
------------------------------------------------------------
* Start pose θ1 = 45°, θ2 = −45°: tip at (1.5071, 0.7071) m.
* The disc's centre lies from the start tip along the direction 160° + 180°
  (the contact normal at the start points at 160°, back towards the robot) at
  distance ``radius − start_force / stiffness``, so the start force is exactly
  0.7212 N (7.212 mm penetration). Centre ≈ (2.2051, 0.4531) m, radius 0.75 m.
* Tracking 1 N (10 mm penetration) at 1 cm per step counter-clockwise about
  the centre (the tip moves down along the disc's left side), the 45-step,
  45 cm path keeps every joint at least 8.7° inside the partitioned ranges
  θ1 ∈ [30°, 60°], θ2 ∈ [−75°, −15°].

| quantity | unit | range / value |
|---|---|---|
| joint angles θ1, θ2 | deg | elbow-down branch (θ2 < 0) |
| tip position | m | world frame, base at origin |
| normal force | N | ≥ 0 |
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from forcelearn.errors import ConfigError


@dataclass(frozen=True)
class ContourGeometry:
    """Arm, surface and start pose of the §4 cell; units in the field names."""

    link1_m: float = 1.0
    link2_m: float = 0.8
    stiffness_n_per_m: float = 100.0
    radius_m: float = 0.75
    normal_angle_deg: float = 160.0
    """Direction (world frame) of the surface normal at the start contact point."""
    start_force_n: float = 0.7212
    start_theta_deg: tuple[float, float] = (45.0, -45.0)
    servo_lag: float = 0.0
    """First-order servo lag per control step, 0 (ideal) <= lag < 1."""
    centre_m: tuple[float, float] = field(init=False)
    """Disc centre, derived so that the start pose presses with ``start_force_n``."""

    def __post_init__(self) -> None:
        if self.link1_m <= 0 or self.link2_m <= 0:
            raise ConfigError("link1_m and link2_m must be > 0")
        if self.stiffness_n_per_m <= 0:
            raise ConfigError("stiffness_n_per_m must be > 0")
        if not 0.0 <= self.servo_lag < 1.0:
            raise ConfigError(f"servo_lag must lie in [0, 1), got {self.servo_lag}")
        penetration_m = self.start_force_n / self.stiffness_n_per_m
        if not 0.0 <= penetration_m < self.radius_m:
            raise ConfigError("start_force_n / stiffness_n_per_m must lie in [0, radius_m)")
        tip = forward_kinematics(self, *self.start_theta_deg)
        normal = math.radians(self.normal_angle_deg)
        distance = self.radius_m - penetration_m
        centre = (tip[0] - distance * math.cos(normal), tip[1] - distance * math.sin(normal))
        object.__setattr__(self, "start_theta_deg", tuple(map(float, self.start_theta_deg)))
        object.__setattr__(self, "centre_m", centre)


def forward_kinematics(geometry: ContourGeometry, theta1_deg: float, theta2_deg: float) -> tuple[
    float, float
]:
    """Return the tool tip (x, y) in m for joint angles in degrees."""
    t1 = math.radians(theta1_deg)
    t12 = t1 + math.radians(theta2_deg)
    return (
        geometry.link1_m * math.cos(t1) + geometry.link2_m * math.cos(t12),
        geometry.link1_m * math.sin(t1) + geometry.link2_m * math.sin(t12),
    )


def inverse_kinematics(geometry: ContourGeometry, x_m: float, y_m: float) -> tuple[float, float]:
    """Return (θ1, θ2) in degrees, elbow-down branch (θ2 <= 0), reaching tip (x, y) in m."""
    l1, l2 = geometry.link1_m, geometry.link2_m
    c2 = (x_m * x_m + y_m * y_m - l1 * l1 - l2 * l2) / (2.0 * l1 * l2)
    if not -1.0 <= c2 <= 1.0:
        raise ValueError(f"tip ({x_m}, {y_m}) m is out of the arm's reach")
    t2 = -math.acos(c2)
    t1 = math.atan2(y_m, x_m) - math.atan2(l2 * math.sin(t2), l1 + l2 * math.cos(t2))
    return math.degrees(t1), math.degrees(t2)


def normal_force_n(geometry: ContourGeometry, x_m: float, y_m: float) -> float:
    """Return the surface's normal force in N on a tip at (x, y) m (zero out of contact)."""
    cx, cy = geometry.centre_m
    penetration_m = geometry.radius_m - math.hypot(x_m - cx, y_m - cy)
    return geometry.stiffness_n_per_m * penetration_m if penetration_m > 0.0 else 0.0


def polar_angle_rad(geometry: ContourGeometry, x_m: float, y_m: float) -> float:
    """Return the tip's angle about the disc centre in rad (counter-clockwise positive)."""
    cx, cy = geometry.centre_m
    return math.atan2(y_m - cy, x_m - cx)


class TwoLinkContourCell:
    """The stateful §4 cell: joint angles that follow commands, the force they produce."""

    def __init__(self, geometry: ContourGeometry | None = None):
        self.geometry = geometry or ContourGeometry()
        self.theta_deg = self.geometry.start_theta_deg

    def reset(self) -> tuple[float, float]:
        """Return the arm to the start pose; return its joint angles in degrees."""
        self.theta_deg = self.geometry.start_theta_deg
        return self.theta_deg

    def move(self, theta1_cmd_deg: float, theta2_cmd_deg: float) -> tuple[float, float]:
        """Apply one joint-angle command through the servo; return the reached angles (deg)."""
        keep = self.geometry.servo_lag
        t1, t2 = self.theta_deg
        self.theta_deg = (
            theta1_cmd_deg + keep * (t1 - theta1_cmd_deg),
            theta2_cmd_deg + keep * (t2 - theta2_cmd_deg),
        )
        return self.theta_deg

    def tip_m(self) -> tuple[float, float]:
        """Return the tool tip (x, y) in m."""
        return forward_kinematics(self.geometry, *self.theta_deg)

    def force_n(self) -> float:
        """Return the normal contact force in N at the present pose."""
        return normal_force_n(self.geometry, *self.tip_m())
