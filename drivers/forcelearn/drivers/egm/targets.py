"""Poses the EGM driver may adopt or send: a caller's target, the controller's feedback.

Pure checks. :func:`clean_target` turns whatever a caller passed into a
:class:`Pose` of plain floats, or raises ``InvalidTarget`` where it was passed;
:func:`unsafe_reason` tells why a pose may not be adopted or sent (not finite,
not a unit quaternion, outside the client workspace), or None.
"""

from __future__ import annotations

import math

from forcelearn.devices import Pose
from forcelearn.drivers.limits import Limits
from forcelearn.drivers.targets import finite_number, unit_quaternion
from forcelearn.errors import InvalidTarget

FEEDBACK_NORM_TOLERANCE = 1e-3
"""The controller's feedback quaternion may be this far off unit norm (it is float arithmetic)."""


def clean_target(pose: object) -> Pose:
    """Return ``pose`` as a Pose of finite floats with a unit 4-element quaternion.

    Raises:
        InvalidTarget: not a Pose, a coordinate not a finite number, or the
            quaternion not 4 finite numbers of unit norm (within 1e-6).
    """
    if not isinstance(pose, Pose):
        raise InvalidTarget(f"a target must be a Pose, got {type(pose).__name__}; nothing was sent")
    x, y, z = (finite_number(getattr(pose, a), f"target {a}") for a in ("x_mm", "y_mm", "z_mm"))
    return Pose(x, y, z, unit_quaternion(pose.quaternion, "target quaternion"))


def unsafe_reason(pose: Pose | None, limits: Limits, tolerance: float) -> str | None:
    """Why ``pose`` may not be adopted or sent, or None when it is finite, unit and inside.

    A pose that passes is found so by the same comparisons written out (every
    ramp step is checked: one each 4 ms cycle); a refusal is worded by
    :func:`_unsafe_reason`.
    """
    if pose is not None and len(q := pose.quaternion) == 4:
        x, y, z = pose.x_mm, pose.y_mm, pose.z_mm
        q0, q1, q2, q3 = q
        finite = math.isfinite
        if (finite(x) and finite(y) and finite(z) and finite(q0) and finite(q1) and finite(q2)
                and finite(q3)):
            # sum()'s additions, from 0.0 (a square is never -0.0: the same float)
            norm = math.sqrt(q0 * q0 + q1 * q1 + q2 * q2 + q3 * q3)
            low, high = limits.workspace_min_mm, limits.workspace_max_mm
            if (abs(norm - 1.0) <= tolerance and low[0] <= x <= high[0]
                    and low[1] <= y <= high[1] and low[2] <= z <= high[2]):
                return None
    return _unsafe_reason(pose, limits, tolerance)


def _unsafe_reason(pose: Pose | None, limits: Limits, tolerance: float) -> str | None:
    """:func:`unsafe_reason` step by step, each refusal worded."""
    if pose is None:
        return "no Cartesian pose"
    values = (pose.x_mm, pose.y_mm, pose.z_mm, *pose.quaternion)
    if len(pose.quaternion) != 4 or not all(math.isfinite(v) for v in values):
        return f"a pose that is not 4 + 3 finite numbers: {values}"
    norm = math.sqrt(sum(c * c for c in pose.quaternion))
    if not abs(norm - 1.0) <= tolerance:
        return f"a quaternion of norm {norm:.6f}, not unit length"
    low, high = limits.workspace_min_mm, limits.workspace_max_mm
    position = (pose.x_mm, pose.y_mm, pose.z_mm)
    if any(not low[i] <= position[i] <= high[i] for i in range(3)):
        return (
            f"position {[round(c, 3) for c in position]} mm outside the workspace box "
            f"{list(low)}..{list(high)} (limits.workspace_*_mm)"
        )
    return None
