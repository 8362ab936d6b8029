r"""The path task: what ``[task] kind = "path"`` configures, checked before any move.

The path task's configuration, read by the cell config
(``forcelearn.site.part_config``) and run by ``forcelearn run``
(:mod:`forcelearn.tasks.path`). The keys map
FC Pressure's arguments (docs/path.md):

=========================  =========================================  =====================
key                        meaning                                    FC Pressure
=========================  =========================================  =====================
``kind``                   ``"surface"`` (§5, default) or ``"path"``  (none)
``path``                   CSV or RAPID file, relative to the config  the taught robtargets
``proc``                   the RAPID PROC that holds the pass         the routine
``force_axis``             tool-frame direction of the force          ``\Fx | \Fy | \Fz``
``desired_force_n``        the force to hold, N                       its value
``tolerance_n``            force error at which r = 1, N              (none)
``contact_threshold_pct``  % of the force that marks contact          ``ForceThreshold``
``force_ramp_n_s``         force ramp at first contact, N/s           ``\ForceChange``
``max_deviation_mm``       largest offset along the force axis        ``\PosSupvDist``
``approach_mm``            start this far back along the axis         the approach move
``retreat_mm``             end this far back along the axis           ``FCPressEnd``
``points_per_pass``        resample to this many (0: as taught)       (none)
``max_turn_deg``           largest turn between two points, deg       ``FCSupvReoriSpeed``
``on_contact_loss``        ``"retreat"`` or ``"continue"``            (none)
``press_stiffness_n_per_mm``  the stiffest part expected, N/mm (press   (none)
                           guard before the probe)
``zero_check``             a zero check in free space after each pass (none)
=========================  =========================================  =====================
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np

from forcelearn.config import build
from forcelearn.devices import STANDARD_GRAVITY_M_S2
from forcelearn.errors import ConfigError, PathRefused
from forcelearn.paths import (
    PathLimits,
    TaughtPath,
    read_path_csv,
    read_rapid,
    resample_path,
    validate_path,
)
from forcelearn.paths.taught import rotation_from_wxyz
from forcelearn.tasks.evaluation import ForceEvaluation

TASK_KINDS = ("surface", "path")
"""The values of ``[task] kind``; ``surface`` (the paper's §5) is the default."""
RAPID_SUFFIXES = (".mod", ".modx", ".prg", ".sys", ".sysx")
CONTACT_LOSS = ("retreat", "continue")


def task_kind(table: Mapping[str, Any] | None) -> str:
    """The ``kind`` of a ``[task]`` table (``surface`` if absent); an unknown kind is named."""
    kind = (table or {}).get("kind", "surface")
    if kind not in TASK_KINDS:
        raise ConfigError(f"task.kind = {kind!r}: must be one of {', '.join(TASK_KINDS)}")
    return str(kind)


def _finite(value: object) -> bool:
    return isinstance(value, int | float) and not isinstance(value, bool) and math.isfinite(value)


@dataclass(frozen=True)
class PathTaskSpec:
    """The path task's keys (module docstring); defaults from FC Pressure programs' use."""

    path: str
    """The taught path: a CSV (``x_mm,y_mm,z_mm,qw,qx,qy,qz``) or a RAPID module."""
    kind: str = "path"
    proc: str | None = None
    """The RAPID PROC; default ``main``, else the module's only PROC."""
    force_axis: tuple[float, float, float] = (0.0, 0.0, 1.0)
    """Tool-frame direction the tool presses along (unit): tool z, as FC Pressure's ``\\Fz``."""
    desired_force_n: float = 2.0 * STANDARD_GRAVITY_M_S2
    tolerance_n: float | None = None
    """Force error at which r = 1, N; default half the desired force (as §5)."""
    contact_threshold_pct: float = 25.0
    """Contact is reached above this % of the desired force (public programs: 15-50 %)."""
    force_ramp_n_s: float = 100.0
    """Force ramp once in contact, N/s (public programs: 75-100 N/s)."""
    max_deviation_mm: float = 15.0
    """Largest offset the learner may command along the force axis, mm (§5's max_offset)."""
    approach_mm: float = 20.0
    """The pass starts this far back from the first point along the force axis, mm."""
    retreat_mm: float = 20.0
    """The pass ends this far back from the last point along the force axis, mm."""
    points_per_pass: int = 0
    """Points per pass after resampling by arc length; 0: the taught points as they are."""
    max_turn_deg: float = 5.0
    """Largest turn of the tool between two consecutive points, deg."""
    on_contact_loss: str = "retreat"
    """Where contact is expected and lost: ``retreat`` (end the pass) or ``continue``."""
    press_stiffness_n_per_mm: float = 20.0
    """The stiffest part the site expects, N/mm: the press guard's stiffness before the probe
    pass measured the part's (as the §5 task's key; docs/on-site.md)."""
    zero_check: bool = True
    """Read free space after each pass's retreat (and the probe's): a moved zero voids it."""

    def __post_init__(self) -> None:
        if self.kind != "path":
            raise ConfigError(f"task.kind = {self.kind!r}: this spec is the path task's")
        if not (isinstance(self.path, str) and self.path):
            raise ConfigError("task.path: give the taught path, a CSV or RAPID file")
        if self.proc is not None and not (isinstance(self.proc, str) and self.proc):
            raise ConfigError(f"task.proc = {self.proc!r}: the name of a PROC")
        axis = self.force_axis
        if not (isinstance(axis, tuple) and len(axis) == 3 and all(map(_finite, axis))
                and abs(math.hypot(*axis) - 1.0) <= 1e-6):
            raise ConfigError(f"task.force_axis = {axis!r}: a unit vector in the tool frame, "
                              "e.g. [0, 0, 1] for tool z")
        for name in ("desired_force_n", "tolerance_n", "force_ramp_n_s", "max_deviation_mm",
                     "max_turn_deg", "press_stiffness_n_per_mm"):
            value = getattr(self, name)
            if value is not None and not (_finite(value) and value > 0):
                raise ConfigError(f"task.{name} = {value!r}: must be a finite number > 0")
        for name in ("approach_mm", "retreat_mm"):
            value = getattr(self, name)
            if not (_finite(value) and value >= 0):
                raise ConfigError(f"task.{name} = {value!r}: must be a finite number >= 0")
        threshold = self.contact_threshold_pct
        if not (_finite(threshold) and 0 < threshold < 100):
            raise ConfigError(f"task.contact_threshold_pct = {threshold!r}: a % of the desired "
                              "force, between 0 and 100 (FC Pressure's ForceThreshold)")
        points = self.points_per_pass
        if isinstance(points, bool) or not isinstance(points, int) or points == 1 or points < 0:
            raise ConfigError(f"task.points_per_pass = {points!r}: 0 (as taught) or a whole "
                              "number >= 2")
        if not isinstance(self.zero_check, bool):
            raise ConfigError(f"task.zero_check = {self.zero_check!r}: true or false")
        if self.on_contact_loss not in CONTACT_LOSS:
            raise ConfigError(f"task.on_contact_loss = {self.on_contact_loss!r}: one of "
                              f"{', '.join(CONTACT_LOSS)}")
        suffix = Path(self.path).suffix.lower()
        if suffix != ".csv" and suffix not in RAPID_SUFFIXES:
            raise ConfigError(f"task.path = {self.path!r}: a .csv file or a RAPID module "
                              f"({', '.join(RAPID_SUFFIXES)})")
        if suffix == ".csv" and self.proc is not None:
            raise ConfigError("task.proc applies to RAPID modules; task.path is a CSV file")

    @property
    def tolerance(self) -> float:
        """Force error at which r = 1, N."""
        return self.desired_force_n / 2.0 if self.tolerance_n is None else self.tolerance_n

    @property
    def evaluation(self) -> ForceEvaluation:
        """The task's r, failure rule and scale (tasks/evaluation.py, shared with §5)."""
        return ForceEvaluation(self.desired_force_n, self.tolerance)

    @property
    def contact_force_n(self) -> float:
        """The force that marks contact, N."""
        return self.desired_force_n * self.contact_threshold_pct / 100.0


def build_path_task(table: Mapping[str, Any], config_dir: str | Path | None) -> PathTaskSpec:
    """Build the spec from a ``[task]`` table; ``path`` is made relative to ``config_dir``."""
    spec = build(PathTaskSpec, table, "task")
    if config_dir is not None and not Path(spec.path).is_absolute():
        spec = replace(spec, path=str(Path(config_dir) / spec.path))
    return spec


def load_task_path(spec: PathTaskSpec, workspace_min_mm: tuple[float, float, float],
                   workspace_max_mm: tuple[float, float, float], max_step_mm: float) -> TaughtPath:
    """Read, resample and check the task's path, with its approach and retreat points.

    Raises a :class:`~forcelearn.errors.PathError` naming the file, line or point
    before anything moves (``safety.*`` are the cell's limits).
    """
    if Path(spec.path).suffix.lower() == ".csv":
        path = read_path_csv(spec.path)
    else:
        path = read_rapid(spec.path, spec.proc)
    if spec.points_per_pass:
        path = resample_path(path, spec.points_per_pass)
    validate_path(path, PathLimits(workspace_min_mm, workspace_max_mm, max_step_mm,
                                   spec.max_turn_deg))
    low, high = np.array(workspace_min_mm), np.array(workspace_max_mm)
    axes = rotation_from_wxyz(path.quaternions_wxyz).apply(spec.force_axis)
    for distance, what in ((spec.approach_mm, "approach"), (spec.retreat_mm, "retreat")):
        # every point's: the return to the start, a failed step's retreat and a fault's
        # retract leave the path there
        points = path.positions_mm - distance * axes
        for index in np.flatnonzero(np.any((points < low) | (points > high), axis=1))[:1]:
            where = ", ".join(f"{v:.6g}" for v in points[index])
            raise PathRefused(int(index), path.names[index], path.lines[index],
                              f"its {what} point ({where}) mm, {distance:g} mm back along the "
                              f"force axis (task.{what}_mm), is outside the workspace")
    return path
