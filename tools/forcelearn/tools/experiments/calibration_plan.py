"""What ``forcelearn calibrate`` does where: the free-space position, the orientations, the times.

The default plan holds the tool centre point at (900, 0, 450) mm, inside the
default ``[safety]`` workspace (700, -60, -130)..(1100, 60, 700) mm and 430 mm
above the sponge (which fills y <= ~0 for z in -120..20 mm), and turns the tool
about that fixed point through nine static orientations:

=====================================  =========================================
orientation                            gravity in the sensor frame
=====================================  =========================================
tool down                              +z
tilted 60 deg about world +x, +y,      60 deg from +z towards +y, +x, -y, -x
-x, -y
tilted 35 deg about the four world     35 deg from +z towards the four
diagonals (+x+y, -x+y, -x-y, +x-y)     diagonals of the sensor's x-y plane
=====================================  =========================================

(condition number of the fit 3.0; none points the tool up). A poses
file (TOML) replaces them::

    position_mm = [900.0, 0.0, 450.0]     # optional
    [[pose]]
    name = "tool down"
    quaternion = [0.0, 1.0, 0.0, 0.0]     # w, x, y, z: sensor frame -> world
    [[pose]]
    name = "tilt +x 60"
    tilt_axis = [1.0, 0.0, 0.0]           # world axis, horizontal
    tilt_deg = 60.0                       # turn of tool-down about it
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass

import numpy as np

from forcelearn.calibration import MAX_CONDITION, TOOL_DOWN
from forcelearn.config import read_toml
from forcelearn.devices import multiply_quaternions
from forcelearn.errors import ConfigError

Quaternion = tuple[float, float, float, float]


def tilted(axis_world: tuple[float, float, float], angle_deg: float) -> Quaternion:
    """Return tool-down turned by ``angle_deg`` about a world axis through the tool point."""
    axis = np.asarray(axis_world, dtype=float)
    norm = float(np.linalg.norm(axis))
    if not norm > 0:
        raise ValueError("tilt axis must not be zero")
    half = math.radians(angle_deg) / 2
    ax, ay, az = (float(c) for c in axis)
    sin_half = math.sin(half)
    turn = (math.cos(half), ax * sin_half / norm, ay * sin_half / norm, az * sin_half / norm)
    q = np.asarray(multiply_quaternions(turn, TOOL_DOWN))
    w, x, y, z = (float(c) for c in q / np.linalg.norm(q))
    return (w, x, y, z)


def slerp_steps(q0: Quaternion, q1: Quaternion, max_step_deg: float) -> list[Quaternion]:
    """Return orientations from q0 (excluded) to q1 (included), each at most ``max_step_deg``."""
    a, b = np.asarray(q0, dtype=float), np.asarray(q1, dtype=float)
    a, b = a / np.linalg.norm(a), b / np.linalg.norm(b)
    dot = float(a @ b)
    if dot < 0:  # the short way round
        b, dot = -b, -dot
    angle = 2 * math.acos(min(1.0, dot))
    count = max(1, math.ceil(math.degrees(angle) / max_step_deg))
    steps = []
    for i in range(1, count + 1):
        f = i / count
        if angle < 1e-9:
            q = b
        else:
            half = angle / 2
            q = (math.sin((1 - f) * half) * a + math.sin(f * half) * b) / math.sin(half)
        q = q / np.linalg.norm(q)
        steps.append(tuple(float(c) for c in q))
    return steps  # type: ignore[return-value]


@dataclass(frozen=True)
class NamedPose:
    """One orientation of the plan: a name for people and a quaternion (w, x, y, z)."""

    name: str
    quaternion: Quaternion


DEFAULT_POSES: tuple[NamedPose, ...] = (
    NamedPose("tool down", TOOL_DOWN),
    *(NamedPose(f"tilt 60 deg about world {n}", tilted(a, 60.0)) for n, a in (
        ("+x", (1.0, 0.0, 0.0)), ("+y", (0.0, 1.0, 0.0)),
        ("-x", (-1.0, 0.0, 0.0)), ("-y", (0.0, -1.0, 0.0)))),
    *(NamedPose(f"tilt 35 deg about world {n}", tilted(a, 35.0)) for n, a in (
        ("+x+y", (1.0, 1.0, 0.0)), ("-x+y", (-1.0, 1.0, 0.0)),
        ("-x-y", (-1.0, -1.0, 0.0)), ("+x-y", (1.0, -1.0, 0.0)))),
)


@dataclass(frozen=True)
class CalibrationPlan:
    """Where and how long to measure (mm, s, deg)."""

    position_mm: tuple[float, float, float] = (900.0, 0.0, 450.0)
    """Free-space tool-point position held for every orientation."""
    poses: tuple[NamedPose, ...] = DEFAULT_POSES
    record_s: float = 5.0
    """Bias-and-noise recording time."""
    samples_per_pose: int = 500
    """Samples averaged at each orientation."""
    settle_s: float = 0.5
    """Dwell after the robot is in position before the settling check."""
    settle_timeout_s: float = 10.0
    """Longest wait for the robot to be in position and the reading to settle."""
    max_rotation_step_deg: float = 10.0
    """Largest orientation change per move command between orientations."""
    revisit_every: int = 2
    """Measure the first orientation again after every this many poses, and at the end: the
    bias drift's knots (0: never, the bias fitted constant)."""
    max_condition: float = MAX_CONDITION
    repeat_rotation_step_deg: float = 30.0
    """Largest turn per move command in the passes after the first, which follow the turns the
    first made (in max_rotation_step_deg steps, the force limit read after each) and whose
    range is predicted at every step: fewer stops, so less bias drift between poses."""
    max_passes: int = 16
    """Most passes over the orientations (with revisits) to bring the centre of mass's sigma
    under its target (forcelearn.tools.commands.calibrate_precision; 1: one pass)."""

    def __post_init__(self) -> None:
        for name in ("record_s", "settle_timeout_s", "max_rotation_step_deg",
                     "repeat_rotation_step_deg"):
            if not (math.isfinite(getattr(self, name)) and getattr(self, name) > 0):
                raise ConfigError(f"calibration {name} must be > 0, got {getattr(self, name)}")
        if not (math.isfinite(self.settle_s) and self.settle_s >= 0):
            raise ConfigError(f"calibration settle_s must be >= 0, got {self.settle_s}")
        if self.max_passes < 1:
            raise ConfigError(f"calibration max_passes must be >= 1, got {self.max_passes}")
        if self.revisit_every < 0:
            raise ConfigError(f"calibration revisit_every must be >= 0, got {self.revisit_every}")
        if self.samples_per_pose < 10:
            raise ConfigError(f"calibration samples_per_pose must be >= 10, "
                              f"got {self.samples_per_pose}")
        if not all(math.isfinite(c) for c in self.position_mm) or len(self.position_mm) != 3:
            raise ConfigError(f"calibration position_mm must be 3 finite numbers, "
                              f"got {self.position_mm}")


def load_poses(
    path: str | os.PathLike[str],
) -> tuple[tuple[NamedPose, ...], tuple[float, float, float] | None]:
    """Read a poses file; return (poses, position_mm or None). Errors name the key."""
    data = read_toml(path)
    source = f"poses file {os.fspath(path)!r}"
    unknown = sorted(set(data) - {"pose", "position_mm"})
    if unknown:
        raise ConfigError(f"{source}: unknown key(s) {unknown}; known: pose, position_mm")
    position = data.get("position_mm")
    if position is not None and (
        not isinstance(position, list) or len(position) != 3
        or not all(isinstance(c, int | float) and not isinstance(c, bool) for c in position)
    ):
        raise ConfigError(f"{source}: position_mm must be 3 numbers (x, y, z) in mm")
    raw = data.get("pose")
    if not isinstance(raw, list) or not raw:
        raise ConfigError(f"{source}: needs [[pose]] tables, one per orientation")
    poses = [_pose(entry, i, source) for i, entry in enumerate(raw)]
    position_mm = None
    if position:
        x, y, z = (float(c) for c in position)  # three numbers, checked above
        position_mm = (x, y, z)
    return tuple(poses), position_mm


def _pose(entry: object, index: int, source: str) -> NamedPose:
    where = f"{source}: pose[{index}]"
    if not isinstance(entry, dict):
        raise ConfigError(f"{where} must be a table")
    unknown = sorted(set(entry) - {"name", "quaternion", "tilt_axis", "tilt_deg"})
    if unknown:
        raise ConfigError(f"{where}: unknown key(s) {unknown}; known: name, quaternion, "
                          "tilt_axis, tilt_deg")
    name = str(entry.get("name", f"pose {index + 1}"))
    if "quaternion" in entry and ("tilt_axis" in entry or "tilt_deg" in entry):
        raise ConfigError(f"{where}: give either quaternion or tilt_axis + tilt_deg, not both")
    try:
        if "quaternion" in entry:
            q = np.asarray(entry["quaternion"], dtype=float)
            if q.shape != (4,) or not np.all(np.isfinite(q)) or abs(np.linalg.norm(q) - 1) > 1e-3:
                raise ValueError("quaternion must be 4 numbers (w, x, y, z) of unit length")
            w, x, y, z = (float(c) for c in q / np.linalg.norm(q))
            return NamedPose(name, (w, x, y, z))
        axis = np.asarray(entry["tilt_axis"], dtype=float)
        if axis.shape != (3,) or abs(axis[2]) > 1e-9 * max(1.0, float(np.abs(axis).max())):
            raise ValueError("tilt_axis must be 3 numbers, horizontal (z = 0)")
        return NamedPose(name, tilted(tuple(axis), float(entry["tilt_deg"])))
    except KeyError as exc:
        raise ConfigError(f"{where}: missing {exc.args[0]} (give quaternion, or tilt_axis and "
                          "tilt_deg)") from exc
    except (TypeError, ValueError) as exc:
        raise ConfigError(f"{where}: {exc}") from exc
