"""The planned pose's ramp toward the target, and the pose arithmetic it needs (pure).

Every EgmSensor reply moves the planned pose toward the target by at most a
distance and an angle per sample period (:func:`step_toward`): position
linearly, orientation along the shorter quaternion arc, both by the same
fraction so the two arrive together. Distances in mm, angles in degrees.
"""

from __future__ import annotations

import math

import numpy as np

from forcelearn.devices import Pose, blend_poses

TURN_DEG_S = 45.0
"""Largest rate at which the planned orientation turns toward the target (assumption)."""


def finite_pose(pose: Pose | None) -> bool:
    """Whether ``pose`` is there and all 7 of its numbers are finite."""
    return pose is not None and len(pose.quaternion) == 4 and all(
        math.isfinite(v) for v in (pose.x_mm, pose.y_mm, pose.z_mm, *pose.quaternion)
    )


def angle_deg(q0: tuple[float, ...], q1: tuple[float, ...]) -> float:
    """Rotation angle between two quaternions, degrees (inf if either is not finite or zero).

    Unit quaternions are used as they are; others are normalised first (a
    controller's datagram may carry any four numbers).
    """
    n0, n1 = math.hypot(*q0), math.hypot(*q1)
    if not (math.isfinite(n0) and math.isfinite(n1) and n0 > 0 and n1 > 0):
        return math.inf
    if abs(n0 - 1.0) > 1e-6 or abs(n1 - 1.0) > 1e-6:
        q0, q1 = tuple(c / n0 for c in q0), tuple(c / n1 for c in q1)
    dot = abs(float(np.dot(q0, q1)))
    return math.degrees(2.0 * math.acos(min(1.0, dot)))


def distance_mm(p0: Pose, p1: Pose) -> float:
    """Distance between two poses' positions, mm (inf, never a warning, if it overflows)."""
    return math.hypot(p0.x_mm - p1.x_mm, p0.y_mm - p1.y_mm, p0.z_mm - p1.z_mm)


def step_toward(pose: Pose, target: Pose, max_mm: float, max_deg: float) -> Pose:
    """Return ``pose`` moved toward ``target`` by at most ``max_mm`` and ``max_deg``."""
    if pose == target and max_mm >= 0.0 and max_deg >= 1e-3 and finite_pose(pose):
        return target  # at rest (most cycles): no distance nor angle to compute
    error = target.position_mm - pose.position_mm
    distance = float(np.linalg.norm(error))
    turn = angle_deg(pose.quaternion, target.quaternion)
    if distance <= max_mm and turn <= max_deg:
        return target
    fraction = min(
        max_mm / distance if distance > 0 else 1.0, max_deg / turn if turn > 0 else 1.0
    )
    return blend_poses(pose, target, fraction)
