"""The refusals a taught path meets before any move, each naming the point and the reason.

=====================  ================================================================
too few points         fewer than ``min_points``
non-unit quaternion    ``| |q| - 1 | > quaternion_tolerance`` (default 1e-3)
outside the workspace  a position outside ``[workspace_min_mm, workspace_max_mm]``
step too long          two consecutive positions further apart than ``max_step_mm``
orientation jump       two consecutive orientations more than ``max_turn_deg`` apart
=====================  ================================================================

The checks run in that order and the first failure is raised as
:class:`~forcelearn.errors.PathRefused`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from forcelearn.errors import PathRefused
from forcelearn.paths.taught import (
    QUATERNION_TOLERANCE,
    TaughtPath,
    quaternion_norm_error,
    rotation_from_wxyz,
)

__all__ = ["QUATERNION_TOLERANCE", "PathLimits", "step_lengths_mm", "turn_angles_deg",
           "validate_path"]


@dataclass(frozen=True)
class PathLimits:
    """What a path may do: workspace box (mm, base frame), step (mm), turn (deg), points."""

    workspace_min_mm: tuple[float, float, float]
    workspace_max_mm: tuple[float, float, float]
    max_step_mm: float
    max_turn_deg: float
    min_points: int = 2
    quaternion_tolerance: float = QUATERNION_TOLERANCE

    def __post_init__(self) -> None:
        low, high = np.array(self.workspace_min_mm), np.array(self.workspace_max_mm)
        if low.shape != (3,) or high.shape != (3,) or not np.all(low < high):
            raise ValueError("workspace_min_mm must be below workspace_max_mm on every axis, "
                             f"got {self.workspace_min_mm} and {self.workspace_max_mm}")
        for name in ("max_step_mm", "max_turn_deg", "quaternion_tolerance"):
            if not getattr(self, name) > 0:
                raise ValueError(f"{name} must be > 0, got {getattr(self, name)}")
        if self.min_points < 2:
            raise ValueError(f"min_points must be >= 2, got {self.min_points}")


def step_lengths_mm(path: TaughtPath) -> np.ndarray:
    """Distance (mm) from each pose to the next, (n - 1,)."""
    return np.asarray(np.linalg.norm(np.diff(path.positions_mm, axis=0), axis=1), dtype=float)


def turn_angles_deg(path: TaughtPath) -> np.ndarray:
    """Rotation angle (deg) from each orientation to the next, (n - 1,)."""
    turns = rotation_from_wxyz(path.quaternions_wxyz)
    return np.asarray(np.degrees((turns[:-1].inv() * turns[1:]).magnitude()), dtype=float)


def validate_path(path: TaughtPath, limits: PathLimits) -> None:
    """Raise :class:`PathRefused` at the first point that breaks ``limits``."""
    if len(path) < limits.min_points:
        raise _refuse(path, len(path) - 1, f"the path has {len(path)} point(s); at least "
                      f"{limits.min_points} are needed")
    norm_error = quaternion_norm_error(path.quaternions_wxyz)
    for i in np.flatnonzero(~(norm_error <= limits.quaternion_tolerance))[:1]:
        norm = np.linalg.norm(path.quaternions_wxyz[i])
        raise _refuse(path, int(i), f"|q| = {norm:.6g} is not a unit quaternion (tolerance "
                      f"{limits.quaternion_tolerance:g}): check the orientation's four values")
    low, high = np.array(limits.workspace_min_mm), np.array(limits.workspace_max_mm)
    outside = np.any((path.positions_mm < low) | (path.positions_mm > high), axis=1)
    for i in np.flatnonzero(outside)[:1]:
        raise _refuse(path, int(i), f"position {_mm(path.positions_mm[i])} mm is outside the "
                      f"workspace {_mm(low)} .. {_mm(high)} mm (safety.workspace_min_mm/_max_mm)")
    steps = step_lengths_mm(path)
    for i in np.flatnonzero(steps > limits.max_step_mm)[:1]:
        raise _refuse(path, int(i) + 1, f"{steps[i]:.3g} mm from the point before, more than "
                      f"max_step_mm = {limits.max_step_mm:g}: add points or resample")
    turns = turn_angles_deg(path)
    for i in np.flatnonzero(turns > limits.max_turn_deg)[:1]:
        raise _refuse(path, int(i) + 1, f"the tool turns {turns[i]:.3g} deg from the point "
                      f"before, more than {limits.max_turn_deg:g} deg: add points or resample")


def _mm(values: np.ndarray) -> str:
    return "(" + ", ".join(f"{v:.6g}" for v in values) + ")"


def _refuse(path: TaughtPath, index: int, reason: str) -> PathRefused:
    index = max(index, 0)
    name = path.names[index] if len(path) else ""
    line = path.lines[index] if len(path) else 0
    return PathRefused(index, name, line, reason)
