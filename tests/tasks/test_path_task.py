"""The path task on a fake cell: a foam plane under a tool that tilts along the path.

The fake cell moves at once and reads the force of a linear foam whose skin is
the plane z = 0 (stiffness k, the force along the world z, i.e. along the tool's
pressing axis times cos(tilt)), with an optional slot cut across it (x in a
band: no force). It records every target it was sent, so a test can check that
no pressing move went deeper than ``max_deviation_mm`` below the taught path.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from forcelearn.devices import Pose
from forcelearn.errors import ForceLimitExceeded
from forcelearn.learning import SRVLearner, SRVParams
from forcelearn.paths import TaughtPath
from forcelearn.tasks.path import PathTask, offset_output
from forcelearn.tasks.path_probe import probe_pass, warm_start
from forcelearn.tasks.path_spec import PathTaskSpec
from forcelearn.trainer import CONVERGENCE_TOLERANCE, train

POINTS = 12
TILT_DEG = 20.0
"""The tool turns from -TILT to +TILT about y along the path (40 deg in all)."""


def tilted_path(points: int = POINTS) -> TaughtPath:
    """Points on the skin z = 0 along x, tool z pointing down into it, tilting about y."""
    angles = np.linspace(-TILT_DEG, TILT_DEG, points)
    turns = Rotation.from_euler("y", angles[:, None], degrees=True) * Rotation.from_euler("x", 180,
                                                                                  degrees=True)
    xyzw = turns.as_quat()
    wxyz = xyzw[:, [3, 0, 1, 2]]
    wxyz = np.where(wxyz[:, :1] < 0, -wxyz, wxyz)
    positions = np.column_stack([np.linspace(0.0, 55.0, points), np.zeros(points),
                                 np.zeros(points)])
    return TaughtPath(positions, wxyz)


@dataclass
class Filtered:
    """The filter's last estimate."""
    force_n: float = 0.0


@dataclass
class FoamPlaneCell:
    """A cell whose tool presses a foam plane z <= 0; moves are instant and recorded."""

    stiffness_n_per_mm: float = 2.0
    slot_x_mm: tuple[float, float] | None = None
    max_force_n: float = 60.0
    stage: tuple[str, int] = ("move", 0)
    time_s: float = 0.0
    force_filter: Filtered = field(default_factory=Filtered)
    targets: list[Pose] = field(default_factory=list)
    _pose: Pose = field(default_factory=lambda: Pose(20.0, 0.0, 200.0))

    @property
    def pose(self) -> Pose:
        """Where the tool is."""
        return self._pose

    def sync(self) -> Pose:
        """The pose, as commanded."""
        return self._pose

    def force_at(self, pose: Pose) -> float:
        """The foam's force at a pose, N."""
        if self.slot_x_mm is not None and self.slot_x_mm[0] <= pose.x_mm <= self.slot_x_mm[1]:
            return 0.0
        return self.stiffness_n_per_mm * max(0.0, -pose.z_mm)

    def move_in_steps(self, target: Pose, max_step_mm: float, guard_force: bool = False) -> int:
        """Go there at once; record the target; the force limit when guarded."""
        self.targets.append(target)
        self._pose = target
        self.time_s += 0.1
        if guard_force and self.force_at(target) > self.max_force_n:
            raise ForceLimitExceeded("fake limit")
        return 1

    def tare(self, max_reading_n: float) -> bool:
        """Nothing to zero."""
        return True

    def reset_filter(self) -> None:
        """No filter to reset."""

    def measure_force_n(self, samples: int | None = None) -> float:
        """The force here, exact."""
        self.force_filter.force_n = self.force_at(self._pose)
        return self.force_filter.force_n


def make_task(cell: FoamPlaneCell, **keys: object) -> PathTask:
    """A path task over :func:`tilted_path` on ``cell``."""
    spec = PathTaskSpec(path="fake.csv", **keys)  # type: ignore[arg-type]
    return PathTask(cell, spec, tilted_path(), max_step_mm=10.0, stiffness_n_per_mm=1.0)


def learner_for(task: PathTask, seed: int = 0) -> SRVLearner:
    """Probe, then a learner warm-started from it."""
    probe = probe_pass(task)
    task.output = offset_output(probe.scale_mm, task.spec.max_deviation_mm)
    learner = SRVLearner(task.grid, 1, SRVParams(extent=(3,)), rng=seed, output=task.output)
    warm_start(learner, probe)
    return learner


def deepest_offsets_mm(cell: FoamPlaneCell, task: PathTask) -> list[float]:
    """Each target's offset along its point's force axis (> 0 deeper than the taught path)."""
    path = task.points
    out = []
    for target in cell.targets:
        k = int(np.argmin(np.abs(path.positions_mm[:, 0] - target.x_mm)))
        here = np.array([target.x_mm, target.y_mm, target.z_mm])
        out.append(float((here - path.positions_mm[k]) @ path.axes[k]))
    return out


def test_a_pass_visits_every_point_turning_and_ends_in_band() -> None:
    """Probe, warm start and 4 passes: every point, every orientation, in band."""
    cell = FoamPlaneCell()
    task = make_task(cell)
    learner = learner_for(task)
    along_axis = cell.stiffness_n_per_mm * math.cos(math.radians(TILT_DEG))  # point 0 tilts
    assert task.stiffness_n_per_mm == pytest.approx(along_axis, rel=1e-6)
    result = train(learner, task, 4)
    band = CONVERGENCE_TOLERANCE * task.desired_force_n
    assert all(not r.failed and r.steps == POINTS for r in result.records)
    assert result.records[-1].force_rms_n <= band
    turned = {tuple(round(v, 6) for v in t.quaternion) for t in cell.targets}
    assert len(turned) >= POINTS  # the tool took every point's orientation
    # a tilted tool must press deeper along its axis for the same force
    rows = result.last_log.rows if result.last_log else []
    assert rows[0]["offset_mm"] > rows[POINTS // 2]["offset_mm"]


def test_contact_lost_continue_records_the_points_and_never_chases_beyond_the_limit() -> None:
    """A slot: its points are recorded, passes go on, no move deeper than the limit."""
    cell = FoamPlaneCell(slot_x_mm=(24.0, 31.0))
    task = make_task(cell, on_contact_loss="continue", max_deviation_mm=12.0)
    learner = learner_for(task)
    result = train(learner, task, 5)
    lost = {point for _, point in task.lost_points}
    in_slot = {k for k in range(POINTS) if 24.0 <= task.points.positions_mm[k, 0] <= 31.0}
    assert lost == in_slot and lost
    assert all(r.steps == POINTS for r in result.records)  # the passes went on
    assert task.largest_offset_mm <= 12.0
    assert max(deepest_offsets_mm(cell, task)) <= 12.0 + 1e-9


def test_contact_lost_retreat_ends_the_pass_and_backs_off() -> None:
    """With retreat the pass ends at the slot and backs off retreat_mm."""
    cell = FoamPlaneCell(slot_x_mm=(24.0, 31.0))
    task = make_task(cell, on_contact_loss="retreat", retreat_mm=12.0)
    learner = learner_for(task)
    result = train(learner, task, 2)
    first_lost = min(point for _, point in task.lost_points)
    assert all(r.failed and r.steps == first_lost for r in result.records)
    last = cell.targets[-1]
    assert deepest_offsets_mm(cell, task)[-1] == pytest.approx(-12.0)
    assert last.x_mm == pytest.approx(task.points.pose(first_lost, -12.0).x_mm)


def test_the_force_limit_fails_the_step_and_is_learned_as_a_failure() -> None:
    """A step past the force limit fails and is evaluated."""
    cell = FoamPlaneCell(max_force_n=25.0)
    task = make_task(cell, max_deviation_mm=15.0)
    task.reset()
    outcome = task.step(np.array([14.0]))  # 14 mm deep: 28 N on the fake foam
    assert outcome.failed and outcome.extras["limit_hit"] == 1.0
    assert math.isfinite(outcome.r)


def test_the_probe_fills_a_point_it_lost_from_its_neighbours() -> None:
    """A point the probe lost gets its neighbours' target and the widest search."""
    cell = FoamPlaneCell(slot_x_mm=(24.0, 31.0))
    task = make_task(cell, on_contact_loss="continue")
    probe = probe_pass(task)
    assert probe.lost and all(probe.r_hats[k] == 1.0 for k in probe.lost)
    k = probe.lost[0]
    assert min(probe.targets_mm[k - 1], probe.targets_mm[k + 1]) <= probe.targets_mm[k] <= max(
        probe.targets_mm[k - 1], probe.targets_mm[k + 1])


@dataclass
class BranchFoamCell(FoamPlaneCell):
    """A foam plane that pushes (1 + h) harder after a press deeper, (1 - h) after easing off."""

    hysteresis: float = 0.2
    _depth_mm: float = 0.0
    _branch: float = 1.0

    def move_in_steps(self, target: Pose, max_step_mm: float, guard_force: bool = False) -> int:
        """As the plane's, following the branch of the last depth change."""
        depth = max(0.0, -target.z_mm)
        if depth != self._depth_mm:
            self._branch = 1.0 if depth > self._depth_mm else -1.0
        self._depth_mm = depth
        return super().move_in_steps(target, max_step_mm, guard_force)

    def force_at(self, pose: Pose) -> float:
        """The plane's force on the present branch, N."""
        return super().force_at(pose) * (1.0 + self.hysteresis * self._branch)


def test_a_probe_that_alternates_between_branches_is_smoothed_and_scaled() -> None:
    """Hysteresis: the targets' point-to-point alternation is removed, the scale stiffened."""
    plain = probe_pass(make_task(FoamPlaneCell()))
    assert plain.pass_stiffness_n_per_mm is None  # settled: targets as measured
    probe = probe_pass(make_task(BranchFoamCell()))
    raw_swing = np.abs(np.diff(probe.offsets_mm[2:])).max()
    assert raw_swing > 1.0  # the correction jumped between branches
    assert np.abs(np.diff(probe.targets_mm)).max() < 0.25 * raw_swing
    assert probe.pass_stiffness_n_per_mm is not None
    assert probe.pass_stiffness_n_per_mm > probe.stiffness_n_per_mm
    assert probe.scale_mm < 0.25 * probe.tolerance_n / probe.stiffness_n_per_mm


def test_the_path_probe_fits_a_stiff_foam_it_meets_in_one_step() -> None:
    """12 N/mm at 5 N, the contact exactly on a 1 mm step: the stiffness fitted, not assumed.

    With the search's own step one reading passed the desired force and the probe fell back
    to 5 N over 10 mm (0.5 N/mm).
    """
    task = make_task(FoamPlaneCell(stiffness_n_per_mm=12.0), desired_force_n=5.0)
    probe = probe_pass(task)
    along_axis = 12.0 * math.cos(math.radians(TILT_DEG))  # the first point's tool is tilted
    assert probe.stiffness_n_per_mm == pytest.approx(along_axis, rel=0.01)
    assert max(probe.forces_n) < 2 * 5.0
