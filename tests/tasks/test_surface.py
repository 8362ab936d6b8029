"""SurfaceTask on a fake cell: its trial (reset, steps, retract), its evaluation, its failures."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
import pytest

from forcelearn.devices import Pose
from forcelearn.errors import ForceLimitExceeded
from forcelearn.tasks.evaluation import FAILURE_R, SAFETY_R, ForceEvaluation
from forcelearn.tasks.surface import SurfaceCell, SurfaceTask, SurfaceTaskSpec, SurfaceYOutput


@dataclass
class _Filter:
    force_n: float = 0.0


@dataclass
class FakeCell:
    """A linear sponge under a robot that moves at once: F = k · max(0, surface − y) (N, mm)."""

    stiffness_n_per_mm: float = 2.0
    surface_y_mm: float = 5.0
    max_force_n: float = 200.0
    stage: tuple[str, int] = ("move", 0)
    time_s: float = 0.0
    force_filter: _Filter = field(default_factory=_Filter)
    moves: list[tuple[Pose, bool, tuple[str, int]]] = field(default_factory=list)
    tares: list[Pose] = field(default_factory=list)
    _pose: Pose = field(default_factory=lambda: Pose(900.0, 15.0, 0.0))

    @property
    def pose(self) -> Pose:
        """Where the robot is."""
        return self._pose

    def force_at(self, pose: Pose) -> float:
        """The sponge's force at ``pose``, N."""
        return self.stiffness_n_per_mm * max(0.0, self.surface_y_mm - pose.y_mm)

    def sync(self) -> Pose:
        """Nothing to read: the fake is where it was told."""
        return self._pose

    def move_in_steps(self, target: Pose, max_step_mm: float, guard_force: bool = False) -> int:
        """Jump to ``target``; a guarded move stops past the force limit."""
        self._pose = target
        self.time_s += 0.1
        self.moves.append((target, guard_force, self.stage))
        force = self.force_at(target)
        self.force_filter.force_n = force
        if guard_force and force > self.max_force_n:
            raise ForceLimitExceeded(f"{force:.1f} N > {self.max_force_n:g} N")
        return 1

    def tare(self, max_reading_n: float) -> bool:
        """Record where the sensor was zeroed."""
        self.tares.append(self._pose)
        return True

    def reset_filter(self) -> None:
        """Nothing filtered."""

    def measure_force_n(self, samples: int | None = None) -> float:
        """The sponge's force where the robot is."""
        return self.force_at(self._pose)


def _task(cell: FakeCell, **spec: Any) -> SurfaceTask:
    shaped: SurfaceCell = cell  # the fake satisfies the task's cell protocol (mypy checks it)
    return SurfaceTask(shaped, SurfaceTaskSpec(**spec), max_step_mm=10.0)


def test_reset_retracts_approaches_from_above_and_presses_to_the_start() -> None:
    """Reset: retract plane, above the start, then a guarded press; the start force is read."""
    cell = FakeCell()
    task = _task(cell)
    spec = task.spec
    x = task.reset()
    assert x.tolist() == [0.0]
    retract, approach, press = (move for move, _, _ in cell.moves[-3:])
    assert retract.y_mm == approach.y_mm == spec.retract_y_mm
    assert (approach.x_mm, approach.z_mm) == (spec.start_mm[0], spec.start_mm[2])
    assert press.position_mm.tolist() == list(spec.start_mm) and cell.moves[-1][1]  # guarded
    assert task.start_force_n == pytest.approx(cell.force_at(spec.start_pose()))
    assert cell.tares == []


def test_a_tare_each_trial_zeroes_in_free_space_above_the_start() -> None:
    """With tare_each_trial the sensor is zeroed at the retract plane, before the press."""
    cell = FakeCell()
    task = _task(cell, tare_each_trial=True)
    task.reset()
    assert len(cell.tares) == 1
    assert cell.tares[0].y_mm == task.spec.retract_y_mm
    assert cell.force_at(cell.tares[0]) == 0.0


def test_a_step_goes_one_z_step_to_the_commanded_y_and_evaluates_the_force() -> None:
    """Step k commands (start x, y, start z + k · z_step); r = |F − F_d| / tolerance."""
    cell = FakeCell()
    task = _task(cell)
    spec = task.spec
    task.reset()
    y = cell.surface_y_mm - 0.8 * spec.desired_force_n / cell.stiffness_n_per_mm
    outcome = task.step(np.array([y]))
    target, guarded, stage = cell.moves[-1]
    assert (target.y_mm, target.z_mm) == (y, spec.start_mm[2] + spec.z_step_mm)
    assert guarded and stage == ("step", 1)
    force = cell.force_at(target)
    assert outcome.force_n == force
    assert outcome.force_error_n == pytest.approx(force - spec.desired_force_n)
    assert outcome.r == pytest.approx(abs(force - spec.desired_force_n) / spec.tolerance)
    assert not outcome.failed and outcome.extras["limit_hit"] == 0.0
    assert outcome.x.tolist() == [abs(spec.z_step_mm)]  # the travel before the next step


@pytest.mark.parametrize("tolerance_n", [None, 2.0])
def test_a_force_outside_the_tolerance_fails_and_retracts(tolerance_n: float | None) -> None:
    """An error past the tolerance fails the step (r > 1) and the robot retracts."""
    cell = FakeCell()
    task = _task(cell, tolerance_n=tolerance_n)
    spec = task.spec
    task.reset()
    error = 1.5 * spec.tolerance
    y = cell.surface_y_mm - (spec.desired_force_n + error) / cell.stiffness_n_per_mm
    outcome = task.step(np.array([y]))
    assert outcome.failed and outcome.r == pytest.approx(1.5)
    assert cell.pose.y_mm == spec.retract_y_mm and cell.stage == ("retreat", 0)


def test_the_force_limit_fails_the_step_with_the_safety_evaluation() -> None:
    """A guarded move stopped by the force limit is a failure learned as r = SAFETY_R."""
    cell = FakeCell(max_force_n=30.0)
    task = _task(cell)
    task.reset()
    pressed_n = 40.0  # past the 30 N limit
    outcome = task.step(np.array([cell.surface_y_mm - pressed_n / cell.stiffness_n_per_mm]))
    assert outcome.failed and outcome.r == SAFETY_R and outcome.extras["limit_hit"] == 1.0
    assert outcome.force_n == pytest.approx(pressed_n)  # the filter's, when the limit stopped it
    assert cell.pose.y_mm == task.spec.retract_y_mm


def test_the_last_step_of_the_path_retracts() -> None:
    """A pass that reaches the path's end retracts; the steps before it stay in contact."""
    cell = FakeCell()
    task = _task(cell, steps_per_trial=3)
    task.reset()
    y = cell.surface_y_mm - task.spec.desired_force_n / cell.stiffness_n_per_mm
    outcomes = [task.step(np.array([y])) for _ in range(3)]
    assert [o.failed for o in outcomes] == [False] * 3
    assert [o.r for o in outcomes] == pytest.approx([0.0] * 3)
    assert cell.pose.y_mm == task.spec.retract_y_mm


def test_the_start_press_follows_the_maps_start_press_and_shift() -> None:
    """With an output map the start press is the map's, moved by its tracked shift."""
    cell = FakeCell()
    output = SurfaceYOutput(-5.0, 2.0, 10.0, start_press_y_mm=-3.0, wear_stiffness_n_per_mm=2.0)
    output.shift_mm = -0.5
    task = SurfaceTask(cell, SurfaceTaskSpec(), 10.0, output)
    assert task.output_map() is output
    assert task.start_pose().y_mm == -3.5
    task.reset()
    assert cell.moves[-1][0].y_mm == -3.5


def test_the_evaluation_is_the_one_the_scale_converts_with() -> None:
    """r, the failure edge and the newtons-to-r scale agree (ratio and error_n are inverses)."""
    spec = SurfaceTaskSpec(tolerance_n=4.0)
    evaluation = spec.evaluation
    assert evaluation == ForceEvaluation(spec.desired_force_n, 4.0)
    edge = evaluation.evaluate(spec.desired_force_n + evaluation.error_n(FAILURE_R))
    assert edge.r == FAILURE_R and not edge.failed  # r = 1 is the edge, not past it
    beyond = evaluation.evaluate(spec.desired_force_n - 4.001)
    assert beyond.failed and beyond.force_error_n < 0
    assert evaluation.ratio(evaluation.error_n(0.37)) == pytest.approx(0.37)
    stopped = evaluation.evaluate(spec.desired_force_n, limit_hit=True)
    assert stopped.failed and stopped.r == SAFETY_R
