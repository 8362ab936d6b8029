"""Poses the EGM driver may adopt or send: a caller's target, the controller's feedback.

Pure checks. :func:`clean_target` turns whatever a caller passed into a
:class:`Pose` of plain floats, or raises ``InvalidTarget`` where it was passed;
:func:`unsafe_reason` tells why a pose may not be adopted or sent (not finite,
not a unit quaternion, outside the client workspace), or None.
"""

from __future__ import annotations

import math

from forcelearn.devices import Pose
from forcelearn.drivers.computer_link.config import Limits
from forcelearn.errors import InvalidTarget

TARGET_NORM_TOLERANCE = 1e-6
"""A caller's quaternion must have a norm within this of 1 (as the computer link asks)."""
FEEDBACK_NORM_TOLERANCE = 1e-3
"""The controller's feedback quaternion may be this far off unit norm (it is float arithmetic)."""


def _number(value: object, what: str) -> float:
    """``value`` as a finite float (numpy scalars too; not a bool or text), else InvalidTarget."""
    try:
        if isinstance(value, bool | str | bytes):
            raise TypeError(value)
        number = float(value)  # type: ignore[arg-type]
    except (TypeError, ValueError, OverflowError):
        raise InvalidTarget(f"{what} must be a number, got {value!r}; nothing was sent") from None
    if not math.isfinite(number):
        raise InvalidTarget(f"{what} must be finite, got {number}; nothing was sent")
    return number


def clean_target(pose: object) -> Pose:
    """Return ``pose`` as a Pose of finite floats with a unit 4-element quaternion.

    Raises:
        InvalidTarget: not a Pose, a coordinate not a finite number, or the
            quaternion not 4 finite numbers of unit norm (within 1e-6).
    """
    if not isinstance(pose, Pose):
        raise InvalidTarget(f"a target must be a Pose, got {type(pose).__name__}; nothing was sent")
    x, y, z = (_number(getattr(pose, a), f"target {a}") for a in ("x_mm", "y_mm", "z_mm"))
    try:
        items = list(pose.quaternion)
    except TypeError:
        raise InvalidTarget(
            f"target quaternion must be 4 numbers (w, x, y, z), got {pose.quaternion!r}; "
            "nothing was sent"
        ) from None
    if len(items) != 4:
        raise InvalidTarget(
            f"target quaternion must be 4 numbers (w, x, y, z), got {len(items)}: {items}; "
            "nothing was sent"
        )
    w, qx, qy, qz = (_number(c, "target quaternion element") for c in items)
    norm = math.sqrt(w * w + qx * qx + qy * qy + qz * qz)
    if not abs(norm - 1.0) <= TARGET_NORM_TOLERANCE:
        raise InvalidTarget(
            f"target quaternion must be unit length, its norm is {norm:.6f}; nothing was sent"
        )
    return Pose(x, y, z, (w, qx, qy, qz))


def unsafe_reason(pose: Pose | None, limits: Limits, tolerance: float) -> str | None:
    """Why ``pose`` may not be adopted or sent, or None when it is finite, unit and inside."""
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
