"""Paper §5: force tracking on a sponge with the position-controlled robot, single input/output.

The §5 task kind, one entry (docs/tasks.md): :class:`SurfaceTask` runs it on a
cell; its parts are one module each and this module names them all:

================================  ====================================================
:mod:`~forcelearn.tasks.surface_spec`     what the task is (targets, path, partition, band)
:mod:`~forcelearn.tasks.evaluation`       r = |F − F_d| / tolerance, failure above 1
:mod:`~forcelearn.tasks.surface_map`      the output map y(a, x) and its choice from the probe
:mod:`~forcelearn.tasks.surface_probe`    the probe (readings: :mod:`~forcelearn.tasks.surface_fit`)
:mod:`~forcelearn.tasks.surface_warm_start`  the learner's start from the probe
================================  ====================================================

The tool starts pressed into the sponge at ``start`` and moves ``z_step_mm``
(−5 mm) per step for ``steps_per_trial`` (20) steps; learning commands the Y
position (normal to the sponge) at each step; the desired force is 2 kgf
(19.61 N). After a failure or a completed pass the robot retracts along +Y and
returns to the start for the next trial; the sponge wears with every pass.

Choices the paper leaves open (docs/surface.md gives the reasons):

* input: the distance travelled along Z (mm) before the step, in
  ``input_parts`` boxes over the path (one box per step by default);
* output y(a) = centre Y + scale · a (absolute Y command, mm), limited to
  ±half-range from the centre (:mod:`~forcelearn.tasks.surface_map`);
* evaluation r = |force − desired| / tolerance (``tolerance_n``, by default
  half the desired force); a step with r > 1 fails, and so does passing the
  safety force limit (r is then set to 2 for learning).
"""

from __future__ import annotations

import logging
import math
from collections.abc import Callable
from typing import Protocol, TypedDict

import numpy as np

from forcelearn.devices import Pose
from forcelearn.errors import ForceLimitExceeded
from forcelearn.tasks.evaluation import SAFETY_R
from forcelearn.tasks.surface_map import RECENTRE_SHARE, WEAR_GAIN, SurfaceYOutput, step_centre_y_mm
from forcelearn.tasks.surface_spec import (
    FALLBACK_OFFSET_MM,
    FALLBACK_SCALE_MM,
    KGF_N,
    MAX_SAMPLES_PER_STEP,
    SurfaceTaskSpec,
    check_task_limits,
)
from forcelearn.trainer import StepOutcome

__all__ = [
    "FALLBACK_OFFSET_MM",
    "FALLBACK_SCALE_MM",
    "KGF_N",
    "MAX_SAMPLES_PER_STEP",
    "RECENTRE_SHARE",
    "SAFETY_R",
    "WEAR_GAIN",
    "SurfaceCell",
    "SurfaceTask",
    "SurfaceTaskSpec",
    "SurfaceYOutput",
    "TrialTrace",
    "check_task_limits",
    "step_centre_y_mm",
]

log = logging.getLogger(__name__)

PRESSED_IN = -1.0
"""The last-move input of a move that pressed in (or held Y), ``approach = "direction"``."""
EASED_OFF = 1.0
"""The last-move input of a move that eased off."""


class FilteredForce(Protocol):
    """The force filter's last estimate."""

    @property
    def force_n(self) -> float:
        """The filtered normal force, N."""
        ...


class SurfaceCell(Protocol):
    """What the §5 task needs of a cell (:class:`forcelearn.cell.Cell` is one; tests fake it).

    Poses in mm, forces in N, times in s of the cell's (the robot's) clock.
    """

    stage: tuple[str, int]
    """What the cell is doing, for its records: ("step", k), ("retreat", 0) ..."""

    @property
    def pose(self) -> Pose:
        """The last pose commanded or read."""
        ...

    @property
    def time_s(self) -> float:
        """The cell's clock, s."""
        ...

    @property
    def force_filter(self) -> FilteredForce:
        """The force filter (its estimate is read after a force-limit stop)."""
        ...

    def sync(self) -> Pose:
        """Take the robot's commanded target as the cell's pose and read its clock."""
        ...

    def move_in_steps(self, target: Pose, max_step_mm: float, guard_force: bool = False) -> int:
        """Move in steps of at most ``max_step_mm`` (ForceLimitExceeded when guarded)."""
        ...

    def tare(self, max_reading_n: float) -> bool:
        """Zero the sensor here, unless it reads more than ``max_reading_n``."""
        ...

    def reset_filter(self) -> None:
        """Forget the filter's track."""
        ...

    def measure_force_n(self, samples: int | None = None) -> float:
        """Read and filter a burst; return the normal force, N."""
        ...


def read_after(cell: SurfaceCell, moves: Callable[[], None]) -> tuple[float, bool]:
    """Make ``moves``, read the filtered force: (force N, whether the force limit stopped them).

    On a force-limit stop (in a move or the read) the force is the filter's estimate, which the
    task's evaluation judges as a safety failure.
    """
    try:
        moves()
        return cell.measure_force_n(), False
    except ForceLimitExceeded:
        return cell.force_filter.force_n, True


class TrialTrace(TypedDict):
    """What a run keeps of each trial's Y commands (mm)."""

    mean_y_mm: list[float]
    """The mean Y (y of μ) of every step."""
    command_y_mm: list[float]
    """The searched Y command of every step."""
    shift_mm: float
    """How far the range's centre had moved when the trial ran (mm): the wear shift plus the
    re-centring on the learner (0: a map that moved neither way)."""
    force_n: list[float]
    """The filtered force of every step, N (NaN: a checkpoint from before it was kept)."""

class SurfaceTask:
    """The §5 episodic task on a :class:`~forcelearn.cell.Cell` (emulated or real)."""

    name = "surface"

    def __init__(
        self,
        cell: SurfaceCell,
        spec: SurfaceTaskSpec,
        max_step_mm: float,
        output: SurfaceYOutput | None = None,
    ):
        self.cell = cell
        self._output = output
        self.spec = spec
        self.max_step_mm = max_step_mm
        self.steps_per_trial = spec.steps_per_trial
        self.desired_force_n = spec.desired_force_n
        self.evaluation = spec.evaluation
        """r = |F − F_d| / tolerance, failure above 1 (:mod:`forcelearn.tasks.evaluation`)."""
        self.grid = spec.grid()
        self.start_force_n = math.nan
        self.press_in: Callable[[Callable[[], float]], float] | None = None
        """Makes each trial's first press from free space above the start, given the press
        (move in, read; returns the force, N); None: the press alone. The run's
        :meth:`~forcelearn.tools.experiments.fault_recovery.RunRecovery.press_in` checks
        the zero around a press that has nothing to be compared with."""
        self._step = 0
        self._last_y_mm = math.nan
        self._trial_start_s = 0.0

    def output_map(self) -> SurfaceYOutput:
        """The output function y this task expects the learner to use.

        The map given at construction (the probe's choice), else the configured
        or fallback one (:meth:`SurfaceTaskSpec.fallback_centre_y_mm` ...).
        """
        if self._output is not None:
            return self._output
        spec = self.spec
        return SurfaceYOutput(
            spec.fallback_centre_y_mm, spec.fallback_scale_mm, spec.fallback_offset_mm
        )

    @property
    def approach_mm(self) -> float:
        """How far above its command each step starts its press, mm (0: straight there)."""
        return 0.0 if self._output is None else self._output.approach_mm

    def retract(self) -> None:
        """Pull out along +Y to the retract plane (in limited steps)."""
        self.cell.stage = ("retreat", 0)
        pose = self.cell.pose
        self.cell.move_in_steps(
            Pose(pose.x_mm, self.spec.retract_y_mm, pose.z_mm, pose.quaternion), self.max_step_mm
        )

    @property
    def trial_cell_time_s(self) -> float:
        """Cell time (the robot's clock, s) since the present trial began."""
        return self.cell.time_s - self._trial_start_s

    def start_pose(self) -> Pose:
        """Where each trial presses in: ``start_mm`` or the map's start press, + its shift."""
        start = self.spec.start_pose()
        output = self._output
        if output is None:
            return start
        press_y = start.y_mm if output.start_press_y_mm is None else output.start_press_y_mm
        return Pose(start.x_mm, press_y + output.shift_mm, start.z_mm, start.quaternion)

    def reset(self) -> np.ndarray:
        """Retract, travel clear of the sponge to above the start, press in, measure the force.

        Starts from the controller's commanded target (:meth:`Cell.sync`), so a
        resumed run starts exactly as the uninterrupted one would.
        """
        start = self.start_pose()
        self.cell.sync()
        self._trial_start_s = self.cell.time_s
        self.retract()
        self.cell.stage = ("approach", 0)
        self.cell.move_in_steps(
            Pose(start.x_mm, self.spec.retract_y_mm, start.z_mm, start.quaternion),
            self.max_step_mm,
        )
        if self.spec.tare_each_trial:
            self.cell.tare(self.spec.tare_max_reading_n)

        def press() -> float:
            self.cell.move_in_steps(start, self.max_step_mm, guard_force=True)
            self.cell.reset_filter()
            return self.cell.measure_force_n()

        self.start_force_n = press() if self.press_in is None else self.press_in(press)
        if self._output is not None:
            self._output.track_wear(self.start_force_n)
        self._step = 0
        self._last_y_mm = start.y_mm
        return self._input(0.0, PRESSED_IN)

    def step(self, command: np.ndarray) -> StepOutcome:
        """Advance one Z step to the commanded Y; evaluate the filtered force."""
        start = self.spec.start_pose()
        self._step += 1
        travel = self._step * abs(self.spec.z_step_mm)
        y_cmd = float(command[0])
        target = Pose(
            start.x_mm, y_cmd, start.z_mm + self._step * self.spec.z_step_mm, start.quaternion
        )
        self.cell.stage = ("step", self._step)

        def moves() -> None:
            if self.approach_mm > 0:  # from the loading side: the foam's branch is known
                above = Pose(target.x_mm, y_cmd + self.approach_mm, target.z_mm, start.quaternion)
                self.cell.move_in_steps(above, self.max_step_mm, guard_force=True)
            self.cell.move_in_steps(target, self.max_step_mm, guard_force=True)

        force, limit_hit = read_after(self.cell, moves)
        judged = self.evaluation.evaluate(force, limit_hit)
        if judged.failed or self._step == self.steps_per_trial:
            self.retract()
        extras = {"y_cmd_mm": y_cmd, "z_mm": target.z_mm, "limit_hit": float(limit_hit)}
        moved = EASED_OFF if y_cmd > self._last_y_mm else PRESSED_IN
        self._last_y_mm = y_cmd
        return StepOutcome(
            self._input(travel, moved), judged.r, judged.failed, force, judged.force_error_n,
            extras,
        )

    def _input(self, travel_mm: float, moved: float) -> np.ndarray:
        """The learner's input: the travel, and the last move's direction if the grid has it."""
        if self.grid.ndim == 1:
            return np.array([travel_mm])
        return np.array([travel_mm, moved])
