"""Resample a taught path to n points per pass: positions linear, orientations slerp.

The parameter is the arc length along the taught polyline, so the new points
are evenly spaced along it and keep its corners' positions between them. A
segment of zero length that turns the tool cannot be spread along the path
and is refused; a repeated identical pose is dropped.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Slerp

from forcelearn.errors import PathRefused
from forcelearn.paths.taught import TaughtPath, rotation_from_wxyz, wxyz_from_rotation
from forcelearn.paths.validation import step_lengths_mm, turn_angles_deg

_SAME_MM = 1e-9
_SAME_DEG = 1e-9


def resample_path(path: TaughtPath, points: int) -> TaughtPath:
    """``points`` poses evenly spaced by arc length from the first taught pose to the last.

    Each new pose keeps the source line and tool of the taught pose that starts its
    segment; names are dropped (the new points are not taught ones).
    """
    if points < 2:
        raise ValueError(f"points must be >= 2, got {points}")
    steps, turns = step_lengths_mm(path), turn_angles_deg(path)
    for i in np.flatnonzero((steps <= _SAME_MM) & (turns > _SAME_DEG))[:1]:
        raise PathRefused(int(i) + 1, path.names[i + 1], path.lines[i + 1],
                          f"the tool turns {turns[i]:.3g} deg in place: a path resampled by "
                          "arc length cannot spread that turn; move while turning")
    keep = np.concatenate([[0], np.flatnonzero(steps > _SAME_MM) + 1])
    if len(keep) < 2:
        raise PathRefused(0, path.names[0], path.lines[0], "the path has no length to resample")
    positions = path.positions_mm[keep]
    arc = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(positions, axis=0), axis=1))])
    wanted = np.linspace(0.0, arc[-1], points)
    segment = np.clip(np.searchsorted(arc, wanted, side="right") - 1, 0, len(arc) - 2)
    new_positions = np.column_stack([np.interp(wanted, arc, positions[:, k]) for k in range(3)])
    slerp = Slerp(arc, rotation_from_wxyz(path.quaternions_wxyz[keep]))
    new_quaternions = wxyz_from_rotation(slerp(wanted))
    new_positions[-1] = positions[-1]
    source = keep[segment]
    return TaughtPath(
        new_positions, new_quaternions, (), tuple(path.lines[i] for i in source),
        source=path.source, instructions=tuple(path.instructions[i] for i in source),
        tool_names=tuple(path.tool_names[i] for i in source), tools=path.tools,
        notes=(*path.notes, f"resampled from {len(path)} to {points} points by arc length"),
    )
