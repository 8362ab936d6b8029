"""The Cell's guards, against small fakes: force limit, device errors, stepped moves."""

from __future__ import annotations

import math

import numpy as np
import pytest

from forcelearn.cell import Cell
from forcelearn.devices import InPositionWait, Pose, WrenchSample
from forcelearn.errors import (
    ConfigError,
    ForceLimitExceeded,
    InvalidTarget,
    LinkTimeout,
    NotInPosition,
    SensorStale,
)
from forcelearn.filtering import ForceFilter, ForceFilterConfig
from forcelearn.records import BurstRecord, MoveRecord, TareRecord


class FakeRobot:
    """Records moves and stops; can be told to fail."""

    def __init__(self) -> None:
        self.pose = Pose(0.0, 0.0, 0.0)
        self.moves: list[Pose] = []
        self.stops = 0
        self.fail_next = False
        self.waits: list[float] = []
        self.never_in_position = False
        self.time_s = 0.0

    def read_pose(self) -> Pose:
        """Return the last pose."""
        return self.pose

    def move_to(self, pose: Pose) -> None:
        """Record the move, or raise a link timeout when told to."""
        if self.fail_next:
            raise LinkTimeout("no ACK")
        self.moves.append(pose)
        self.pose = pose

    def read_target(self) -> Pose:
        """The target is where the fake is (it arrives at once)."""
        return self.pose

    def wait_in_position(self, timeout_s: float, settle_s: float = 0.0) -> float:
        """Count waits; the fake's clock runs 0.5 s per wait, plus the settle time."""
        self.waits.append(settle_s)
        if self.never_in_position:
            self.stop()
            raise NotInPosition("fake robot never arrives")
        self.time_s += 0.5 + settle_s
        return self.time_s

    def stop(self) -> None:
        """Count stops."""
        self.stops += 1

    def close(self) -> None:
        """Nothing to release."""


class FakeSensor:
    """Returns scripted normal forces on Fy (sign +1); can go stale."""

    def __init__(self, forces: list[float]) -> None:
        self.forces = list(forces)
        self.counter = 0
        self.stale = False
        self.zeroed = 0
        self.samples: list[WrenchSample] = []
        """Whole samples, returned before the scripted forces."""

    def read(self) -> WrenchSample:
        """Return the next scripted sample."""
        if self.stale:
            raise SensorStale("no sample")
        self.counter += 1
        if self.samples:
            return self.samples.pop(0)
        value = self.forces.pop(0) if self.forces else 0.0
        return WrenchSample(np.array([0.0, value, 0, 0, 0, 0]), 0.0, self.counter)

    def zero_offsets(self) -> None:
        """Count the zeroings."""
        self.zeroed += 1

    def close(self) -> None:
        """Nothing to release."""


def make_cell(forces: list[float], max_force_n: float = 50.0) -> tuple[Cell, FakeRobot, FakeSensor]:
    """A cell over the fakes with a filter on +Fy."""
    robot, sensor = FakeRobot(), FakeSensor(forces)
    cell = Cell(
        robot,
        sensor,
        ForceFilter(ForceFilterConfig(axis=1, sign=1.0)),
        max_force_n,
        samples_per_step=3,
    )
    return cell, robot, sensor


def test_force_within_the_limit_is_filtered_and_returned() -> None:
    """Three samples near 10 N give a filtered force near 10 N; the robot is not stopped."""
    cell, robot, _ = make_cell([10.0, 10.1, 9.9])
    assert cell.measure_force_n() == pytest.approx(10.0, abs=0.2)
    assert robot.stops == 0


def test_a_single_sample_over_the_limit_stops_the_robot() -> None:
    """One spike above max_force_n is enough: ForceLimitExceeded, robot stopped."""
    cell, robot, _ = make_cell([10.0, 80.0, 10.0])
    with pytest.raises(ForceLimitExceeded, match="max_force_n"):
        cell.measure_force_n()
    assert robot.stops == 1


@pytest.mark.parametrize("wrench", [[0.0, -80.0, 0, 0, 0, 0], [70.0, 5.0, 0, 0, 0, 0],
                                    [0.0, 5.0, -70.0, 0, 0, 0]])
def test_a_force_off_the_normal_or_against_its_sign_still_stops_the_robot(wrench: list[float]):
    """The limit is on the force's magnitude: a wrong axis or sign cannot press on unseen."""
    cell, robot, sensor = make_cell([10.0, 10.0, 10.0])
    sensor.samples = [WrenchSample(np.array(wrench), 0.0, 1)]
    with pytest.raises(ForceLimitExceeded, match="check that axis and sign"):
        cell.measure_force_n()
    assert robot.stops == 1


def test_a_saturated_sample_stops_the_robot_whatever_it_reads() -> None:
    """Near full scale the force is not known: a stop, naming the axis."""
    cell, robot, sensor = make_cell([10.0, 10.0])
    flags = (False, False, False, False, True, False)
    sensor.samples = [WrenchSample(np.array([0.0, 10.0, 0, 0, 0, 0]), 0.0, 1, flags)]
    with pytest.raises(ForceLimitExceeded, match="full scale on My"):
        cell.measure_force_n()
    assert robot.stops == 1


def test_a_stale_sensor_stops_the_robot() -> None:
    """SensorStale propagates after the robot was stopped."""
    cell, robot, sensor = make_cell([])
    sensor.stale = True
    with pytest.raises(SensorStale):
        cell.measure_force_n()
    assert robot.stops == 1


def test_a_link_error_during_a_move_stops_the_robot() -> None:
    """Any device error on a move stops the robot before it propagates."""
    cell, robot, _ = make_cell([])
    robot.fail_next = True
    with pytest.raises(LinkTimeout):
        cell.move_to(Pose(1.0, 0.0, 0.0))
    assert robot.stops == 1


def test_long_moves_are_cut_into_steps_under_the_limit() -> None:
    """A 95 mm move with a 10 mm limit takes 10 steps, none over 10 mm, ending on target."""
    cell, robot, _ = make_cell([])
    count = cell.move_in_steps(Pose(0.0, 95.0, 0.0), max_step_mm=10.0)
    assert count == 10 and len(robot.moves) == 10
    positions = [Pose(0, 0, 0).position_mm] + [p.position_mm for p in robot.moves]
    steps = np.linalg.norm(np.diff(positions, axis=0), axis=1)
    assert steps.max() <= 10.0
    assert robot.moves[-1].y_mm == pytest.approx(95.0)


@pytest.mark.parametrize("limit", [0.0, -1.0, float("inf"), float("nan")])
def test_the_force_limit_cannot_be_switched_off(limit: float) -> None:
    """A zero, negative, infinite or NaN force limit is refused."""
    with pytest.raises(ConfigError):
        make_cell([], max_force_n=limit)


def test_guarded_long_moves_check_the_force_after_every_intermediate_step() -> None:
    """Pressing 40 mm in 10 mm steps stops at the step where the force passes the limit."""
    cell, robot, _ = make_cell([5.0, 30.0, 70.0, 90.0], max_force_n=50.0)
    with pytest.raises(ForceLimitExceeded):
        cell.move_in_steps(Pose(0.0, -40.0, 0.0), max_step_mm=10.0, guard_force=True)
    assert len(robot.moves) == 3  # stopped after the third step, never reached the target
    assert robot.stops == 1


def test_a_move_that_would_take_too_many_steps_is_refused_before_any_is_sent() -> None:
    """A step limit of a micrometre would cut 10 mm into 10,102 steps: InvalidTarget, no move."""
    cell, robot, _ = make_cell([])
    with pytest.raises(InvalidTarget, match=r"raise safety\.max_step_mm"):
        cell.move_in_steps(Pose(10.0, 0.0, 0.0), 1e-3)
    assert robot.moves == []
    assert cell.move_in_steps(Pose(10.0, 0.0, 0.0), 1e-2) == 1011  # under the ceiling: moves


def test_a_move_to_where_the_robot_already_is_sends_nothing() -> None:
    """No command leaves for a zero-length move with the same orientation."""
    cell, robot, _ = make_cell([])
    cell.move_to(Pose(1.0, 2.0, 3.0))
    assert cell.move_in_steps(Pose(1.0, 2.0, 3.0), max_step_mm=10.0) == 0
    assert len(robot.moves) == 1


def test_every_move_is_waited_for_and_only_the_last_step_settles() -> None:
    """Each step waits for in-position; the dwell before measuring comes once, at the end."""
    cell, robot, _ = make_cell([])
    cell.move_in_steps(Pose(0.0, 25.0, 0.0), max_step_mm=10.0)
    assert robot.waits == [0.0, 0.0, cell.settle_s]
    assert cell.time_s == robot.time_s  # the cell's time is the robot's clock


def test_a_move_that_never_arrives_stops_the_robot_and_raises() -> None:
    """NotInPosition from the wait propagates after the robot was stopped; no force is read."""
    cell, robot, sensor = make_cell([10.0])
    robot.never_in_position = True
    with pytest.raises(NotInPosition):
        cell.move_to(Pose(0.0, 5.0, 0.0))
    assert robot.stops >= 1
    assert sensor.counter == 0


def test_sync_takes_the_controllers_target_as_the_pose() -> None:
    """sync() reads the commanded target, so a resumed run starts where the controller is."""
    cell, robot, _ = make_cell([])
    robot.pose = Pose(3.0, 4.0, 5.0)
    assert cell.sync() == Pose(3.0, 4.0, 5.0)
    assert cell.pose == Pose(3.0, 4.0, 5.0)


def test_a_tare_zeroes_in_free_space_and_refuses_where_something_pushes() -> None:
    """Free space within the limit: zeroed and the hook told the pose; a large reading: refused.

    Zeroing under a real force would hide it from every later reading (and from
    the force limit), so a reading over ``max_reading_n`` keeps the old zero.
    """
    cell, robot, sensor = make_cell([0.3, 0.2, 0.4, 6.0, 6.1, 5.9])
    told: list[Pose] = []
    cell.on_tare = told.append
    assert cell.tare(max_reading_n=2.0) is True
    assert sensor.zeroed == 1 and told == [robot.pose]
    assert cell.tare(max_reading_n=2.0) is False
    assert sensor.zeroed == 1 and len(told) == 1
    assert (cell.tares, cell.tares_refused) == (1, 1)
    assert robot.stops == 0


def test_compensation_keeps_each_samples_sensor_time() -> None:
    """A compensated sample keeps the sensor time the driver measured (the filter steps by it)."""
    robot, sensor = FakeRobot(), FakeSensor([])
    sensor.samples = [WrenchSample(np.array([0.0, 5.0, 0, 0, 0, 0]), 0.0, 8 * i,
                                   sensor_dt_s=None if i == 0 else 0.001028)
                      for i in range(3)]
    seen: list[WrenchSample] = []

    class Recording(ForceFilter):
        def on_sample(self, sample: WrenchSample) -> None:
            seen.append(sample)
            super().on_sample(sample)

    cell = Cell(robot, sensor, Recording(ForceFilterConfig(axis=1, sign=1.0)), 50.0,
                samples_per_step=3, compensation=lambda wrench, pose: wrench - 1.0)
    assert cell.measure_force_n() == pytest.approx(4.0, abs=0.01)
    assert [s.sensor_dt_s for s in seen] == [None, 0.001028, 0.001028]


class ListRecorder:
    """Keeps whatever the cell hands it (a CellRecorder)."""

    def __init__(self) -> None:
        self.moves: list[MoveRecord] = []
        self.bursts: list[BurstRecord] = []
        self.tares: list[TareRecord] = []

    def on_move(self, move: MoveRecord) -> None:
        """Keep the move."""
        self.moves.append(move)

    def on_burst(self, burst: BurstRecord) -> None:
        """Keep the burst."""
        self.bursts.append(burst)

    def on_tare(self, tare: TareRecord) -> None:
        """Keep the tare."""
        self.tares.append(tare)


def test_a_recorder_gets_every_move_with_its_times_and_the_reached_pose() -> None:
    """Start, first in position (the driver's last wait) and settled; reached when told."""
    cell, robot, _ = make_cell([])
    recorder = cell.recorder = ListRecorder()
    cell.move_to(Pose(1.0, 2.0, 3.0))  # this fake tells no wait: in position = settled
    robot.last_wait = InPositionWait(0.9, Pose(1.0, 2.1, 3.0))  # type: ignore[attr-defined]
    cell.move_to(Pose(1.0, 2.0, 4.0))
    first, second = recorder.moves
    assert first == MoveRecord((1.0, 2.0, 3.0), first.reached_mm, 0.0, 0.55, 0.55)
    assert all(math.isnan(v) for v in first.reached_mm)  # not reported: not made up
    assert second == MoveRecord((1.0, 2.0, 4.0), (1.0, 2.1, 3.0), 0.55, 0.9, 1.1)


def test_a_recorder_gets_each_bursts_statistics_and_the_filters_output() -> None:
    """Mean, std, first and last of the compensated normal force; count; span; filtered."""
    robot, sensor = FakeRobot(), FakeSensor([])
    sensor.samples = [WrenchSample(np.array([1.0, -f, 0, 0, 0, 0.5]), 0.0, i,
                                   sensor_dt_s=None if i == 0 else 0.002)
                      for i, f in enumerate([4.0, 6.0, 8.0])]
    bias = np.array([0.0, 1.0, 0, 0, 0, 0])
    cell = Cell(robot, sensor, ForceFilter(ForceFilterConfig(axis=1, sign=-1.0)), 50.0,
                samples_per_step=3, compensation=lambda wrench, pose: wrench - bias)
    recorder = cell.recorder = ListRecorder()
    cell.time_s = 7.0
    force = cell.measure_force_n()
    (burst,) = recorder.bursts
    assert (burst.mean_n, burst.first_n, burst.last_n, burst.count) == (7.0, 5.0, 9.0, 3)
    assert burst.std_n == pytest.approx(np.std([5.0, 7.0, 9.0]))
    assert burst.start_s == 7.0 and burst.span_s == pytest.approx(0.004)
    assert burst.filtered_n == force
    assert burst.wrench_mean == pytest.approx((1.0, -7.0, 0.0, 0.0, 0.0, 0.5))


def test_a_burst_over_the_limit_is_recorded_before_the_robot_stops() -> None:
    """The reading that stopped the robot is in the records (its filtered force unknown)."""
    cell, robot, _ = make_cell([1.0, 80.0, 1.0])
    recorder = cell.recorder = ListRecorder()
    with pytest.raises(ForceLimitExceeded):
        cell.measure_force_n()
    (burst,) = recorder.bursts
    assert burst.last_n == 1.0 and burst.first_n == 1.0 and burst.mean_n == pytest.approx(82 / 3)
    assert math.isnan(burst.filtered_n) and robot.stops == 1


def test_a_recorder_gets_each_tare_done_or_refused() -> None:
    """Where, when and what the sensor read before zeroing; the trial is the recorder's."""
    cell, _, _ = make_cell([0.3, 0.2, 0.4, 6.0, 6.1, 5.9])
    recorder = cell.recorder = ListRecorder()
    cell.move_to(Pose(5.0, 15.0, 0.0))
    assert cell.tare(2.0) and not cell.tare(2.0)
    done, refused = recorder.tares
    assert done.accepted and not refused.accepted and done.trial == -1
    assert done.position_mm == (5.0, 15.0, 0.0)
    assert abs(done.reading_n) <= 2.0 and refused.reading_n > 2.0


def test_without_a_recorder_the_cell_reads_no_extra_state() -> None:
    """No recorder: the driver's last wait is never looked at (nothing computed)."""
    cell, robot, _ = make_cell([1.0] * 3)

    class Untouchable:
        def __get__(self, obj: object, owner: object) -> None:
            raise AssertionError("read without a recorder")

    type(robot).last_wait = Untouchable()  # type: ignore[attr-defined]
    try:
        cell.move_to(Pose(0.0, 1.0, 0.0))
        cell.measure_force_n()
    finally:
        del type(robot).last_wait  # type: ignore[attr-defined]


@pytest.mark.parametrize("residual", [np.zeros(6), np.array([0.0, 0.25, -0.0, 0.0, 1e-3, 0.0])])
@pytest.mark.parametrize("compensated", [False, True])
def test_a_burst_is_compensated_as_its_samples_one_by_one(residual: np.ndarray,
                                                          compensated: bool) -> None:
    """``_compensated_burst`` (the residual tested once a burst) is ``_compensated`` per sample.

    Its (n, 6) array holds those samples' wrenches, to the bit.
    """
    cell, _, _ = make_cell([])
    cell.zero_residual = residual
    if compensated:
        cell.compensation = lambda wrench, pose: wrench * 0.5
    rng = np.random.default_rng(4)
    batch = [WrenchSample(rng.normal(0.0, 3.0, 6), 0.1 * i, i, sensor_dt_s=0.001 * i or None)
             for i in range(7)]
    burst, wrenches = cell._compensated_burst(batch)
    one_by_one = [cell._compensated(sample) for sample in batch]
    assert len(burst) == len(one_by_one)
    assert wrenches.tobytes() == np.array([s.wrench for s in one_by_one]).tobytes()
    for a, b in zip(burst, one_by_one, strict=True):
        assert a.wrench.tobytes() == b.wrench.tobytes()
        assert (a.timestamp_s, a.counter, a.saturated, a.sensor_dt_s) == (
            b.timestamp_s, b.counter, b.saturated, b.sensor_dt_s)
