"""Waiting for the robot, and the reference of relative moves, against an emulator that takes time.

Every test runs over a pty and over TCP with the emulator's realistic arm
(start delay, speed and acceleration limits, servo lag) unless it says otherwise.
"""

from __future__ import annotations

import pytest

from forcelearn.drivers.computer_link import Limits
from forcelearn.emulators.computer_link import ComputerLinkFaultConfig
from forcelearn.emulators.physics.arm import HOME, ArmConfig
from forcelearn.errors import LinkError, NotInPosition, SafetyStop


def test_wait_in_position_returns_once_the_robot_is_there_and_settled(
    make_emulator, connect
) -> None:
    """Accepted is not arrived: the wait ends in the band, after the settle time, on its clock."""
    emulator = make_emulator(config=ArmConfig())
    robot = connect(emulator.address)
    robot.move_by(dz_mm=-5.0)
    accepted = robot.read_status()
    assert accepted.moving and not accepted.in_position  # still planning or travelling
    done_s = robot.wait_in_position(timeout_s=5.0, settle_s=0.1)
    pose = robot.read_pose()
    assert pose.z_mm == pytest.approx(HOME.z_mm - 5.0, abs=ArmConfig().in_position_mm)
    # delay 0.05 s + about 0.14 s of travel + the lag, then 0.1 s of settling
    assert 0.25 < done_s - accepted.time_s < 1.0
    assert emulator.engine.clock.now_s >= done_s
    # the records' in-position time: when the settle began (no pose: it costs an exchange)
    assert robot.last_wait is not None and robot.last_wait.reached is None
    assert accepted.time_s < robot.last_wait.in_position_s <= done_s - 0.1


def test_a_robot_that_stops_short_ends_the_wait_and_is_stopped(make_emulator, connect) -> None:
    """Stalled half way: NotInPosition after the timeout of controller time; STOP was sent."""
    emulator = make_emulator(config=ArmConfig(), faults=ComputerLinkFaultConfig(stall_fraction=0.5))
    robot = connect(emulator.address)
    robot.move_by(dz_mm=-8.0)
    start = robot.read_status().time_s
    with pytest.raises(NotInPosition, match="move_timeout_s") as error:
        robot.wait_in_position(timeout_s=1.5)
    assert isinstance(error.value, TimeoutError)
    motion = emulator.engine.motion
    assert motion.target.z_mm == pytest.approx(HOME.z_mm - 4.0, abs=0.01)  # STOP: rest point
    assert emulator.engine.clock.now_s - start >= 1.5


def test_a_robot_that_never_reports_in_position_ends_the_wait(make_emulator, connect) -> None:
    """Status never says in position: the wait is bounded by its timeout, not endless."""
    emulator = make_emulator(config=ArmConfig(),
                             faults=ComputerLinkFaultConfig(never_in_position=True))
    robot = connect(emulator.address)
    robot.move_by(dz_mm=-2.0)
    with pytest.raises(NotInPosition):
        robot.wait_in_position(timeout_s=0.8, settle_s=0.05)
    assert emulator.move_count == 1


def test_relative_moves_after_a_lost_link_never_leave_the_workspace(
    make_emulator, connect
) -> None:
    """The reproduction of the review: a slow arm, MOVE_BYs up to the limit, a hang-up, reconnect.

    The driver's reference is the controller's commanded target (READ_TARGET),
    not the pose reached, so the move past the box is refused before sending
    and the controller's target never leaves the client's workspace.
    """
    limit_x = 1000.0
    emulator = make_emulator(config=ArmConfig(lag_s=5.0))
    limits = Limits(workspace_max_mm=(limit_x, 800.0, 1400.0))
    robot = connect(emulator.address, limits=limits)
    for _ in range(11):
        robot.move_by(dx_mm=9.0)
        assert emulator.engine.motion.target.x_mm <= limit_x
    assert emulator.pose.x_mm < HOME.x_mm + 10.0  # the arm lags far behind its target
    emulator._endpoint.hang_up()
    with pytest.raises(LinkError):
        robot.read_status()
    robot.reconnect()
    moves = emulator.move_count
    with pytest.raises(SafetyStop, match="workspace"):
        robot.move_by(dx_mm=9.0)
    assert emulator.move_count == moves == 11
    assert emulator.engine.motion.target.x_mm == pytest.approx(HOME.x_mm + 99.0, abs=1e-3)


def test_after_a_stop_the_reference_is_where_the_controller_brakes_to(
    make_emulator, connect
) -> None:
    """STOP mid-move: the next relative move adds to the controller's rest point."""
    emulator = make_emulator(config=ArmConfig(start_delay_s=0.0, default_speed_mm_s=20.0))
    robot = connect(emulator.address)
    robot.move_by(dz_mm=-9.0)
    robot.read_status()  # some controller time passes: the arm is on its way
    robot.read_status()
    robot.stop()
    rest = emulator.engine.motion.target
    assert HOME.z_mm - 9.0 < rest.z_mm < HOME.z_mm
    robot.move_by(dz_mm=-1.0)
    assert emulator.engine.motion.target.z_mm == pytest.approx(rest.z_mm - 1.0, abs=1e-3)
