"""The planned pose's ramp toward the target, and the pose arithmetic it needs (pure).

Every EgmSensor reply moves the planned pose toward the target by at most a
distance and an angle per sample period (:func:`step_toward`): position
linearly, orientation along the shorter quaternion arc, both by the same
fraction so the two arrive together. Distances in mm, angles in degrees.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from forcelearn.devices import Pose, blend_poses

TURN_DEG_S = 45.0
"""Largest rate at which the planned orientation turns toward the target (assumption)."""


def finite_pose(pose: Pose | None) -> bool:
    """Whether ``pose`` is there and all 7 of its numbers are finite."""
    return pose is not None and len(pose.quaternion) == 4 and all(
        math.isfinite(v) for v in (pose.x_mm, pose.y_mm, pose.z_mm, *pose.quaternion)
    )


_last_angle: tuple[Any, Any, float] = (None, None, 0.0)  # angle_deg's latest (q0, q1, angle)


def angle_deg(q0: tuple[float, ...], q1: tuple[float, ...]) -> float:
    """Rotation angle between two quaternions, degrees (inf if either is not finite or zero).

    Unit quaternions are used as they are; others are normalised first (a
    controller's datagram may carry any four numbers). The latest answer is
    kept: a ramp asks for the same two orientations cycle after cycle (equal
    values give the same angle to the bit: a zero's sign cannot change it,
    and NaN is never equal).
    """
    global _last_angle
    last = _last_angle  # one tuple, replaced whole: drivers in other threads may share it
    if q0 == last[0] and q1 == last[1]:
        return last[2]
    angle = _angle_deg(q0, q1)
    _last_angle = (q0, q1, angle)
    return angle


def _angle_deg(q0: tuple[float, ...], q1: tuple[float, ...]) -> float:
    """:func:`angle_deg` computed."""
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
    error = np.array([target.x_mm - pose.x_mm, target.y_mm - pose.y_mm, target.z_mm - pose.z_mm],
                     dtype=float)  # the arrays' subtraction, component by component
    distance = math.sqrt(float(error.dot(error)))  # numpy.linalg.norm's own operations
    turn = angle_deg(pose.quaternion, target.quaternion)
    if distance <= max_mm and turn <= max_deg:
        return target
    fraction = min(
        max_mm / distance if distance > 0 else 1.0, max_deg / turn if turn > 0 else 1.0
    )
    return blend(pose, target, fraction)


_last_unit: tuple[Any, Any] = (None, None)  # blend's latest (quaternion, normalised)


def blend(a: Pose, b: Pose, fraction: float) -> Pose:
    """:func:`~forcelearn.devices.blend_poses` to the bit, cheaper when the orientation stays.

    The position's three components are the same float operations as the
    array's. When both orientations hold equal values (a ramp that only
    translates) the nlerp is ``q0 + fraction * 0``: ``q0`` with any zero made
    +0.0, which is then normalised as ``blend_poses`` does (the latest kept).
    """
    qa = a.quaternion
    if fraction >= 1.0 or qa != b.quaternion or not math.isfinite(fraction):
        return blend_poses(a, b, fraction)
    global _last_unit
    q = tuple(c + 0.0 for c in qa)
    last = _last_unit  # (one tuple, replaced whole, as angle_deg's)
    if q != last[0]:  # (NaN is never equal: a kept q is finite)
        if not all(math.isfinite(c) for c in q):
            return blend_poses(a, b, fraction)  # inf - inf: not q0 + 0
        unit = np.asarray(q)
        unit = unit / np.linalg.norm(unit)
        last = _last_unit = (q, tuple(float(c) for c in unit))
    return Pose.of(a.x_mm + fraction * (b.x_mm - a.x_mm), a.y_mm + fraction * (b.y_mm - a.y_mm),
                   a.z_mm + fraction * (b.z_mm - a.z_mm), last[1])  # (Pose(...)'s object)
