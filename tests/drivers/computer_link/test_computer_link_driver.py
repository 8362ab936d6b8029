"""The driver against the emulated controller: one test body, run over a pty and over TCP."""

from __future__ import annotations

import threading

import pytest
import serial

from forcelearn.devices import Pose, Robot
from forcelearn.drivers.computer_link import Limits
from forcelearn.emulators.computer_link import ArmConfig, controller
from forcelearn.emulators.physics.arm import HOME, TOOL_DOWN
from forcelearn.emulators.physics.cell import CellPhysics
from forcelearn.errors import LinkError, ProtocolError, RobotFault
from forcelearn.protocols.computer_link import messages as m


def test_open_identifies_and_reads_the_home_pose(emulator, connect) -> None:
    """Opening the link identifies the controller; the pose read is the emulator's home."""
    robot = connect(emulator.address)
    assert isinstance(robot, Robot)
    assert "emulator" in robot.controller_model
    assert robot.read_pose() == HOME
    joints = robot.read_joints_deg()
    assert len(joints) == 6
    assert joints[0] == pytest.approx(0.0)
    assert joints[4] == pytest.approx(180.0)


def test_move_to_and_move_by_reach_the_target_once_and_drive_the_physics(
    make_emulator, connect
) -> None:
    """Each accepted move executes exactly once and the shared physics sees the reached pose."""
    physics = CellPhysics()
    emulator = make_emulator(physics=physics)
    robot = connect(emulator.address)
    target = Pose(901.5, -2.25, 595.0, TOOL_DOWN)
    robot.move_to(target)
    assert emulator.move_count == 1
    assert robot.read_pose() == target
    assert physics.pose == target
    robot.move_by(dx_mm=-1.5, dz_mm=2.0)
    assert emulator.move_count == 2
    assert robot.read_pose() == Pose(900.0, -2.25, 597.0, TOOL_DOWN)
    status = robot.read_status()
    assert (status.moving, status.in_position, status.last_error, status.move_count) == (
        False,
        True,
        0,
        2,
    )


def test_controller_refusal_raises_robot_fault_and_does_not_move(make_emulator, connect) -> None:
    """A target inside the driver's limits but outside the controller's gets RobotFault."""
    emulator = make_emulator(config=ArmConfig(workspace_max_mm=(1500.0, 800.0, 600.0)))
    robot = connect(emulator.address)
    with pytest.raises(RobotFault) as fault:
        robot.move_by(dz_mm=5.0)
    assert fault.value.code == m.ErrorCode.OUT_OF_WORKSPACE
    assert "workspace" in fault.value.reason
    assert emulator.move_count == 0
    assert robot.read_pose() == HOME
    assert robot.read_status().last_error == m.ErrorCode.OUT_OF_WORKSPACE
    robot.move_by(dz_mm=-5.0)  # the link is still usable
    assert emulator.move_count == 1


def test_set_speed_is_obeyed_by_a_lagging_servo(make_emulator, connect) -> None:
    """With a first-order lag and a slow speed the robot is reported moving, not in position."""
    emulator = make_emulator(config=ArmConfig(lag_s=0.02))
    robot = connect(emulator.address)
    robot.set_speed(5.0)
    robot.move_by(dz_mm=-10.0)
    status = robot.read_status()  # 10 mm at 5 mm/s takes 2 s
    assert status.moving
    assert not status.in_position


def test_speed_above_the_controller_maximum_raises_robot_fault(make_emulator, connect) -> None:
    """A speed within the driver's limit but above the controller's gets BAD_SPEED."""
    emulator = make_emulator(config=ArmConfig(max_speed_mm_s=100.0))
    robot = connect(emulator.address, limits=Limits(max_speed_mm_s=200.0))
    with pytest.raises(RobotFault) as fault:
        robot.set_speed(150.0)
    assert fault.value.code == m.ErrorCode.BAD_SPEED


def test_close_stops_the_robot_closes_the_port_and_is_idempotent(make_emulator, connect) -> None:
    """Leaving the context stops motion; a closed driver refuses calls; close twice is fine."""
    emulator = make_emulator(config=ArmConfig(lag_s=0.05, default_speed_mm_s=5.0))
    robot = connect(emulator.address)
    robot.move_by(dz_mm=-10.0)
    with robot:
        pass
    stopped_at = emulator.pose
    assert stopped_at.z_mm > HOME.z_mm - 10.0 + 1.0
    robot.close()
    with pytest.raises(LinkError, match="closed"):
        robot.read_pose()
    assert emulator.pose == stopped_at


def test_concurrent_threads_share_one_driver(emulator, connect) -> None:
    """Four threads moving through one driver: every move executes once, none collide."""
    robot = connect(emulator.address)
    errors: list[BaseException] = []

    def worker(sign: float) -> None:
        try:
            for _ in range(25):
                robot.move_by(dz_mm=sign * 0.5)
        except BaseException as exc:  # recorded for the main thread
            errors.append(exc)

    threads = [threading.Thread(target=worker, args=(s,), daemon=True) for s in (1, -1, 1, -1)]
    for t in threads:
        t.start()
    for t in threads:
        t.join(timeout=20)
    assert not errors
    assert emulator.move_count == 100
    assert robot.read_pose().z_mm == pytest.approx(HOME.z_mm)


def test_emulator_survives_a_client_that_disconnects(emulator, connect) -> None:
    """After one client goes away mid-frame, the next client is served."""
    raw = serial.serial_for_url(emulator.address, timeout=0.05)
    raw.write(b"\x10\x02\x01\x00")  # half a frame, then gone
    raw.close()
    robot = connect(emulator.address)
    robot.move_by(dx_mm=1.0)
    assert emulator.move_count == 1


def test_reply_from_another_protocol_version_is_refused(emulator, connect, monkeypatch) -> None:
    """A controller of another major protocol version is refused at open."""
    monkeypatch.setattr(controller, "VERSION", (3, 0))
    with pytest.raises(ProtocolError, match=r"protocol 3\.0"):
        connect(emulator.address)
