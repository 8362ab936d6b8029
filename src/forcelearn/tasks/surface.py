"""Paper §5: force tracking on a sponge with the position-controlled robot, single input/output.

The tool starts pressed into the sponge at ``start`` and moves ``z_step_mm``
(−5 mm) per step for ``steps_per_trial`` (20) steps; learning commands the Y
position (normal to the sponge) at each step; the desired force is 2 kgf
(19.61 N). After a failure or a completed pass the robot retracts along +Y and
returns to the start for the next trial; the sponge wears with every pass.

Choices the paper leaves open (docs/surface.md gives the reasons):

* input: the distance travelled along Z (mm) before the step, in
  ``input_parts`` boxes over the path (one box per step by default);
* output y(a) = start Y + ``output_scale_mm`` · a (absolute Y command, mm),
  limited to ±``max_offset_mm`` from the start Y;
* evaluation r = |force − desired| / ``tolerance_n``; a step with r > 1 fails,
  and so does passing the safety force limit (r is then set to 2 for learning).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from forcelearn.cell import Cell
from forcelearn.devices import IDENTITY_QUATERNION, Pose
from forcelearn.errors import ConfigError, ForceLimitExceeded
from forcelearn.learning import BoxGrid, Dimension
from forcelearn.trainer import StepOutcome

KGF_N = 9.80665
"""One kilogram-force in newtons."""
SAFETY_R = 2.0
"""Evaluation given to a step stopped by the force limit (a failure, learned as one)."""


@dataclass(frozen=True)
class SurfaceTaskSpec:
    """Targets, path, partition and output map of the §5 task (paper values as defaults)."""

    desired_force_n: float = 2.0 * KGF_N
    """2 kgf (§5)."""
    tolerance_n: float = 10.0
    """Force error at which r = 1 (a failure); about half the desired force."""
    steps_per_trial: int = 20
    z_step_mm: float = -5.0
    start_mm: tuple[float, float, float] = (900.0, -4.0, 0.0)
    """Start pose position: x, y (4 mm into the fresh sponge), z."""
    orientation: tuple[float, float, float, float] = (0.0, 1.0, 0.0, 0.0)
    """Tool orientation quaternion (w, x, y, z): tool pointing down."""
    retract_y_mm: float = 15.0
    """Y of the retract path: 10 mm clear of the highest point of the default sponge."""
    input_parts: int = 20
    output_scale_mm: float = 2.0
    """Millimetres of Y command per action unit."""
    max_offset_mm: float = 15.0
    """Largest |Y command − start Y|, mm (keeps the roller off the sponge's backing)."""
    samples_per_step: int = 0
    """Sensor samples filtered after each move; 0: as many as fit ``measurement_window_s``."""
    measurement_window_s: float = 0.025
    """Time the burst of samples after each settled move spans, s (0.2 N adapter noise with
    1.3 ms correlation: a 25 ms burst filters to ~0.07 N; see docs/results/filter.md)."""
    settle_s: float = 0.05
    """Dwell in position before the force is measured, s (the robot's clock)."""

    def __post_init__(self) -> None:
        if self.steps_per_trial < 1 or self.input_parts < 1 or self.samples_per_step < 0:
            raise ConfigError(
                "task.steps_per_trial and task.input_parts must be >= 1, "
                "task.samples_per_step >= 0 (0: from task.measurement_window_s)"
            )
        if not (math.isfinite(self.measurement_window_s) and self.measurement_window_s > 0):
            raise ConfigError("task.measurement_window_s must be a finite number > 0")
        for name in ("desired_force_n", "tolerance_n", "output_scale_mm", "max_offset_mm"):
            if not getattr(self, name) > 0:
                raise ConfigError(f"task.{name} must be > 0")
        if not (math.isfinite(self.settle_s) and self.settle_s >= 0):
            raise ConfigError("task.settle_s must be a finite number >= 0")
        if self.z_step_mm == 0:
            raise ConfigError("task.z_step_mm must not be 0")
        if self.retract_y_mm <= self.start_mm[1] + self.max_offset_mm:
            raise ConfigError("task.retract_y_mm must lie beyond start Y + max_offset_mm")

    def samples_for(self, sample_period_s: float) -> int:
        """Samples per step: the configured count, or as many as fit the measurement window."""
        if self.samples_per_step:
            return self.samples_per_step
        return max(1, round(self.measurement_window_s / sample_period_s))

    @property
    def path_mm(self) -> float:
        """Length of the path along Z, mm."""
        return abs(self.z_step_mm) * self.steps_per_trial

    def grid(self) -> BoxGrid:
        """The BOXES partition of the distance travelled (one box per step by default)."""
        half = 0.5 * self.path_mm / self.input_parts
        return BoxGrid([Dimension("travel_mm", -half, self.path_mm - half, self.input_parts)])

    def start_pose(self) -> Pose:
        """The pose each trial starts from."""
        return Pose(*self.start_mm, self.orientation or IDENTITY_QUATERNION)


class SurfaceYOutput:
    """y(a) = start Y + scale · a, limited to ±max_offset: an absolute Y command in mm."""

    def __init__(self, start_y_mm: float, scale_mm: float, max_offset_mm: float):
        self.start_y_mm = start_y_mm
        self.scale_mm = scale_mm
        self.max_offset_mm = max_offset_mm

    def __call__(self, a: np.ndarray, x: np.ndarray) -> np.ndarray:
        """Return the Y command (mm) for action ``a``."""
        offset = np.clip(a * self.scale_mm, -self.max_offset_mm, self.max_offset_mm)
        return self.start_y_mm + offset


class SurfaceTask:
    """The §5 episodic task on a :class:`~forcelearn.cell.Cell` (emulated or real)."""

    name = "surface"

    def __init__(self, cell: Cell, spec: SurfaceTaskSpec, max_step_mm: float):
        self.cell = cell
        self.spec = spec
        self.max_step_mm = max_step_mm
        self.steps_per_trial = spec.steps_per_trial
        self.desired_force_n = spec.desired_force_n
        self.grid = spec.grid()
        self.start_force_n = math.nan
        self._step = 0
        self._trial_start_s = 0.0

    def output_map(self) -> SurfaceYOutput:
        """The output function y this task expects the learner to use."""
        return SurfaceYOutput(
            self.spec.start_mm[1], self.spec.output_scale_mm, self.spec.max_offset_mm
        )

    def retract(self) -> None:
        """Pull out along +Y to the retract plane (in limited steps)."""
        pose = self.cell.pose
        self.cell.move_in_steps(
            Pose(pose.x_mm, self.spec.retract_y_mm, pose.z_mm, pose.quaternion), self.max_step_mm
        )

    @property
    def trial_cell_time_s(self) -> float:
        """Cell time (the robot's clock, s) since the present trial began."""
        return self.cell.time_s - self._trial_start_s

    def reset(self) -> np.ndarray:
        """Retract, travel clear of the sponge to above the start, press in, measure the force.

        Starts from the controller's commanded target (:meth:`Cell.sync`), so a
        resumed run starts exactly as the uninterrupted one would.
        """
        start = self.spec.start_pose()
        self.cell.sync()
        self._trial_start_s = self.cell.time_s
        self.retract()
        self.cell.move_in_steps(
            Pose(start.x_mm, self.spec.retract_y_mm, start.z_mm, start.quaternion),
            self.max_step_mm,
        )
        self.cell.move_in_steps(start, self.max_step_mm, guard_force=True)
        self.cell.reset_filter()
        self.start_force_n = self.cell.measure_force_n()
        self._step = 0
        return np.array([0.0])

    def step(self, command: np.ndarray) -> StepOutcome:
        """Advance one Z step to the commanded Y; evaluate the filtered force."""
        start = self.spec.start_pose()
        self._step += 1
        travel = self._step * abs(self.spec.z_step_mm)
        y_cmd = float(command[0])
        target = Pose(
            start.x_mm, y_cmd, start.z_mm + self._step * self.spec.z_step_mm, start.quaternion
        )
        try:
            self.cell.move_in_steps(target, self.max_step_mm, guard_force=True)
            force = self.cell.measure_force_n()
            error = force - self.desired_force_n
            r = abs(error) / self.spec.tolerance_n
            limit_hit = False
        except ForceLimitExceeded:
            force = self.cell.force_filter.force_n
            error = force - self.desired_force_n
            r = SAFETY_R
            limit_hit = True
        failed = r > 1.0 or limit_hit
        if failed or self._step == self.steps_per_trial:
            self.retract()
        extras = {"y_cmd_mm": y_cmd, "z_mm": target.z_mm, "limit_hit": float(limit_hit)}
        return StepOutcome(np.array([travel]), r, failed, force, error, extras)
