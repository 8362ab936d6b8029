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

    Each test is written out (every ramp step is checked: one each 4 ms cycle); a
    refusal is worded when it is found.
    """
    if pose is None:
        return "no Cartesian pose"
    q = pose.quaternion
    x, y, z = pose.x_mm, pose.y_mm, pose.z_mm
    finite = math.isfinite
    if len(q) != 4 or not (finite(x) and finite(y) and finite(z) and finite(q[0])
                           and finite(q[1]) and finite(q[2]) and finite(q[3])):
        return f"a pose that is not 4 + 3 finite numbers: {(x, y, z, *q)}"
    # sum(c * c for c in q)'s additions, from 0.0 (a square is never -0.0: the same float)
    norm = math.sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3])
    if not abs(norm - 1.0) <= tolerance:
        return f"a quaternion of norm {norm:.6f}, not unit length"
    low, high = limits.workspace_min_mm, limits.workspace_max_mm
    if not (low[0] <= x <= high[0] and low[1] <= y <= high[1] and low[2] <= z <= high[2]):
        position = (x, y, z)
        return (
            f"position {[round(c, 3) for c in position]} mm outside the workspace box "
            f"{list(low)}..{list(high)} (limits.workspace_*_mm)"
        )
    return None
