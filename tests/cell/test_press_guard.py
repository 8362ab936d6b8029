"""The press guard: no single move pushes a stiff part past the force limit from a reading."""

from __future__ import annotations

import contextlib

import numpy as np
import pytest

from forcelearn.cell import Cell
from forcelearn.devices import InPositionWait, Pose, WrenchSample
from forcelearn.errors import ForceLimitExceeded
from forcelearn.filtering import ForceFilter, ForceFilterConfig
from forcelearn.press_guard import KNOWN_FACTOR, NOISE_SIGMAS, PressGuard

LIMIT_N = 60.0
SURFACE_Y_MM = 0.0
FRESH = 1.25
"""A fresh indentation meets this x the stiffness (the emulated foam's relaxation)."""


class Spring:
    """A robot pressing a part of stiffness ``k`` below y = 0 and a sensor that reads it."""

    def __init__(self, k_n_per_mm: float, y_mm: float = 10.0) -> None:
        self.k = k_n_per_mm
        self.pose = Pose(0.0, y_mm, 0.0)
        self.moves: list[Pose] = []
        self.stops = 0
        self.time_s = 0.0
        self.counter = 0
        self.true_forces: list[float] = []
        """The part's force at every pose the robot reached, N (what no reading may hide)."""

    def force_n(self) -> float:
        """The part's force where the robot is, N (unrelaxed: the worst a move meets)."""
        return FRESH * self.k * max(0.0, SURFACE_Y_MM - self.pose.y_mm)

    # robot
    def read_pose(self) -> Pose:
        """Where the robot is."""
        return self.pose

    def read_target(self) -> Pose:
        """Its target: where it is (it arrives at once)."""
        return self.pose

    def move_to(self, pose: Pose) -> None:
        """Go there; note the part's force there."""
        self.moves.append(pose)
        self.pose = pose
        self.true_forces.append(self.force_n())

    def wait_in_position(self, timeout_s: float, settle_s: float = 0.0) -> float:
        """In position at once; the clock runs 0.1 s per move plus the settle."""
        self.time_s += 0.1 + settle_s
        return self.time_s

    def stop(self) -> None:
        """Count the stops."""
        self.stops += 1

    # sensor
    def read(self) -> WrenchSample:
        """The part's force here, exactly."""
        self.counter += 1
        return WrenchSample(np.array([0.0, self.force_n(), 0, 0, 0, 0]), 0.0, self.counter)

    def zero_offsets(self) -> None:
        """Nothing to zero: the spring reads its force exactly."""

    def close(self) -> None:
        """Nothing to release."""


def spring_cell(k_n_per_mm: float, guard: PressGuard | None) -> tuple[Cell, Spring]:
    """A cell over a spring of ``k_n_per_mm``; ``guard`` bounds its presses."""
    spring = Spring(k_n_per_mm)
    cell = Cell(spring, spring, ForceFilter(ForceFilterConfig(axis=1, sign=1.0)), LIMIT_N,
                samples_per_step=3)
    cell.press_guard = guard
    return cell, spring


def unknown_guard(unknown_n_per_mm: float) -> PressGuard:
    """A guard that knows nothing of the part but the site's stiffest expected one."""
    return PressGuard(LIMIT_N, unknown_n_per_mm, noise_n=0.1)


@pytest.mark.parametrize("k", [8.0, 15.0])
def test_a_press_into_a_stiff_part_never_passes_the_limit_with_the_guard(k: float) -> None:
    """From free space 10 mm above, a guarded move 10 mm into the part: cut, never over."""
    target = Pose(0.0, SURFACE_Y_MM - 10.0, 0.0)
    unguarded, bare = spring_cell(k, None)
    with contextlib.suppress(ForceLimitExceeded):  # read only once past the limit
        unguarded.move_in_steps(target, max_step_mm=10.0, guard_force=True)
    assert max(bare.true_forces) > LIMIT_N  # what the guard is for (the test can fail)

    cell, spring = spring_cell(k, unknown_guard(FRESH * k))
    cell.read_pose()
    cell.measure_force_n()  # the last good reading: free space, 10 mm above the part
    with pytest.raises(ForceLimitExceeded, match="would press past"):
        cell.move_in_steps(target, max_step_mm=10.0, guard_force=True)
    assert max(spring.true_forces) <= LIMIT_N
    assert spring.stops >= 1
    assert len(spring.moves) > len(bare.moves)  # cut into more, shorter moves


def test_a_move_the_prediction_allows_is_not_cut() -> None:
    """A press whose predicted force stays under the limit is one move, as without a guard."""
    k = 2.0
    guard = unknown_guard(FRESH * k)
    cell, spring = spring_cell(k, guard)
    cell.read_pose()
    cell.measure_force_n()
    cell.move_in_steps(Pose(0.0, SURFACE_Y_MM - 5.0, 0.0), max_step_mm=20.0, guard_force=True)
    assert len(spring.moves) == 1 and guard.cuts == 0


def test_easing_off_is_never_cut_and_a_move_at_the_limit_is_refused_unsent() -> None:
    """At a reading near the limit a deeper move sends nothing; leaving the part is free."""
    k = 10.0
    cell, spring = spring_cell(k, unknown_guard(FRESH * k))
    cell.read_pose()
    cell.measure_force_n()
    with pytest.raises(ForceLimitExceeded):
        cell.move_in_steps(Pose(0.0, SURFACE_Y_MM - 20.0, 0.0), 10.0, guard_force=True)
    sent = len(spring.moves)
    with pytest.raises(ForceLimitExceeded, match="would press past"):
        cell.move_in_steps(Pose(0.0, SURFACE_Y_MM - 20.0, 0.0), 10.0, guard_force=True)
    assert len(spring.moves) == sent  # refused before anything was sent
    cell.move_in_steps(Pose(0.0, 10.0, 0.0), 10.0, guard_force=True)
    assert spring.pose.y_mm == 10.0


def test_the_stiffness_in_use_is_known_else_seen_else_the_sites_default() -> None:
    """Nothing known: the default; two readings in contact: what they show; a probe: its fit."""
    guard = PressGuard(LIMIT_N, 20.0, noise_n=0.1)
    assert guard.stiffness_n_per_mm == 20.0
    guard.note(np.array([0.0, 0.0, 0.0]), 5.0)
    guard.note(np.array([0.0, -1.0, 0.0]), 8.0)  # 3 N over 1 mm pressed in
    assert guard.stiffness_n_per_mm == 20.0  # one pair may straddle a fault: not yet
    guard.note(np.array([0.0, -2.0, 0.0]), 11.5)  # 3.5 N over the next 1 mm
    seen = guard.stiffness_n_per_mm
    assert 3.0 < seen < 20.0
    guard.know(10.0)
    assert guard.stiffness_n_per_mm == max(KNOWN_FACTOR * 10.0, seen)
    headroom = LIMIT_N - 11.5 - NOISE_SIGMAS * 0.1
    assert guard.allowed_mm() == pytest.approx(headroom / guard.stiffness_n_per_mm)


def test_a_rise_within_the_noise_measures_no_stiffness() -> None:
    """A rise under 3 sigma over a press-in is noise: the site's default stays in use."""
    guard = PressGuard(LIMIT_N, 20.0, noise_n=1.0)
    guard.note(np.array([0.0, 0.0, 0.0]), 5.0)
    guard.note(np.array([0.0, -0.5, 0.0]), 7.5)  # 2.5 N: under 3 sigma of a 1 N noise
    assert guard.observed_n_per_mm is None
    assert guard.stiffness_n_per_mm == 20.0
    guard.note(np.array([0.0, -1.5, 0.0]), 17.5)  # 10 N over 1 mm: a stiffness
    assert guard.observed_n_per_mm == pytest.approx(10.0) and guard.pairs == 1


class ShortArm(Spring):
    """An arm in position 0.4 mm short of each press (its zone), read there, then creeping on."""

    SHORT_MM = 0.4

    def __init__(self, k_n_per_mm: float) -> None:
        super().__init__(k_n_per_mm)
        self.last_wait: InPositionWait | None = None
        self.commanded = self.pose

    def move_to(self, pose: Pose) -> None:
        """In position short of ``pose`` when pressing in; the force where it creeps to is noted."""
        short = max(0.0, self.pose.y_mm - pose.y_mm) and self.SHORT_MM
        self.pose = pose
        self.moves.append(pose)
        self.true_forces.append(self.force_n())  # the arm ends at the target
        self.pose = Pose(pose.x_mm, pose.y_mm + short, pose.z_mm)  # read in the zone
        self.last_wait = InPositionWait(self.time_s, self.pose)


def test_the_guard_takes_a_reading_where_the_arm_was_not_where_it_was_sent() -> None:
    """An arm short of its target when read: predictions start where it was (never over)."""
    arm = ShortArm(15.0)
    cell = Cell(arm, arm, ForceFilter(ForceFilterConfig(axis=1, sign=1.0)), LIMIT_N,
                samples_per_step=3)
    cell.press_guard = unknown_guard(FRESH * arm.k)
    cell.read_pose()
    cell.measure_force_n()
    with pytest.raises(ForceLimitExceeded, match="would press past"):
        cell.move_in_steps(Pose(0.0, SURFACE_Y_MM - 10.0, 0.0), max_step_mm=1.0,
                           guard_force=True)
    assert max(arm.true_forces) <= LIMIT_N


class DriftingSpring(Spring):
    """A spring whose sensor's zero drifts steadily, reading less force as time goes on."""

    def __init__(self, k_n_per_mm: float, drift_n_per_s: float) -> None:
        super().__init__(k_n_per_mm)
        self.drift_n_per_s = drift_n_per_s

    def read(self) -> WrenchSample:
        """The part's force less the drift so far."""
        self.counter += 1
        reading = self.force_n() - self.drift_n_per_s * self.time_s
        return WrenchSample(np.array([0.0, reading, 0, 0, 0, 0]), 0.0, self.counter)


def test_a_steady_drift_the_zero_checks_measured_never_hides_force_past_the_limit() -> None:
    """Zero checks in free space measure the drift; the guard keeps headroom for it."""
    spring = DriftingSpring(8.0, drift_n_per_s=1.0)
    spring.pose = Pose(0.0, 1.0, 0.0)
    cell = Cell(spring, spring, ForceFilter(ForceFilterConfig(axis=1, sign=1.0)), LIMIT_N,
                samples_per_step=3)
    cell.press_guard = unknown_guard(FRESH * spring.k)
    cell.read_pose()
    cell.check_zero(lambda std: 1e9)  # zeroed in free space
    for i in range(40):  # 4 s in free space: the zero drifts by 4 N
        cell.move_to(Pose(0.0, 1.0 + i % 2, 0.0))
    cell.check_zero(lambda std: 1e9)  # reads the drift since, and zeroes again
    with contextlib.suppress(ForceLimitExceeded):
        cell.move_in_steps(Pose(0.0, SURFACE_Y_MM - 10.0, 0.0), max_step_mm=1.0,
                           guard_force=True)
    assert max(spring.true_forces) <= LIMIT_N


def test_a_drop_easing_off_faster_than_the_stiffness_buys_no_depth() -> None:
    """Eased off 0.5 mm, read 10 N less on a 2 N/mm part: predictions stay on the deeper one.

    An unloading branch or a bias step down: either way the reading before was true.
    """
    guard = PressGuard(LIMIT_N, 2.0, noise_n=0.1)
    guard.note(np.array([0.0, -6.0, 0.0]), 40.0)
    guard.note(np.array([0.0, -5.5, 0.0]), 30.0)
    assert guard.last is not None and guard.last[1] == 40.0
    guard.note(np.array([0.0, -5.0, 0.0]), 39.2)  # 1 mm up, 0.8 N less: the part's own
    assert guard.last[1] == pytest.approx(39.2)


def test_a_first_contact_from_free_space_is_kept_as_a_stiffness_seen_not_used() -> None:
    """30 N over 3 mm from a free-space reading: at least 10 N/mm (the watch widens to it)."""
    guard = PressGuard(LIMIT_N, 20.0, noise_n=0.1)
    guard.note(np.array([0.0, 3.0, 0.0]), 0.0)
    guard.note(np.array([0.0, 0.0, 0.0]), 30.0)
    assert guard.first_contact_n_per_mm == pytest.approx(10.0)
    assert guard.observed_n_per_mm is None and guard.stiffness_n_per_mm == 20.0  # not an upper
    restored = PressGuard(LIMIT_N, 20.0, noise_n=0.1)
    restored.load_state_dict(guard.state_dict())
    assert restored.first_contact_n_per_mm == pytest.approx(10.0)


def test_one_pair_across_a_bias_step_does_not_make_a_stiff_part_look_soft() -> None:
    """A step read as less force between two readings: 0.5 N over 1 mm of an 8 N/mm part.

    Alone it would let the next move press 70 mm; the site's default stays until a second
    pair, and the steepest of the two is used.
    """
    guard = PressGuard(LIMIT_N, 20.0, noise_n=0.05)
    guard.note(np.array([0.0, 0.0, 0.0]), 6.0)
    guard.note(np.array([0.0, -1.0, 0.0]), 6.5)  # 8 N true rise, 7.5 N of it a bias step
    assert guard.stiffness_n_per_mm == 20.0
    guard.note(np.array([0.0, -1.5, 0.0]), 10.5)  # the next pair: 8 N/mm
    assert guard.stiffness_n_per_mm == pytest.approx(1.5 * 8.0)
