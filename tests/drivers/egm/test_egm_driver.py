"""The EGM driver against the emulated controller over loopback UDP (lockstep unless said)."""

from __future__ import annotations

import time
from collections.abc import Callable

import numpy as np
import pytest

from forcelearn.devices import Pose, Robot
from forcelearn.drivers.egm import EgmRobot
from forcelearn.emulators.egm import EgmControllerEmulator, EgmFaultConfig, Fault
from forcelearn.errors import (
    EgmVersionMismatch,
    GuidanceStopped,
    LinkError,
    LinkTimeout,
    SafetyStop,
)
from forcelearn.protocols.egm import codec

HOME = Pose(900.0, 0.0, 600.0, (0.0, 1.0, 0.0, 0.0))
"""The conftest's start pose."""
MakePair = Callable[..., tuple[EgmRobot, EgmControllerEmulator]]


@pytest.mark.parametrize("version", codec.VERSIONS)
def test_move_and_wait_in_position_moves_the_emulated_robot(
    egm_pair: MakePair, version: codec.Version
) -> None:
    """A 5 mm move reaches the target; the shared physics holds the reached pose."""
    robot, emu = egm_pair(driver={"version": version}, controller={"version": version})
    assert isinstance(robot, Robot)
    assert robot.read_pose() == HOME
    robot.move_by(dz_mm=-5.0)
    done_s = robot.wait_in_position(timeout_s=1.0, settle_s=0.02)
    reached = robot.read_pose()
    assert abs(reached.z_mm - 595.0) <= robot.config.in_position_mm
    # the records' view of the wait: in position 20 ms before its end, and the pose then
    assert robot.last_wait is not None and robot.last_wait.reached == reached
    assert robot.last_wait.in_position_s == pytest.approx(done_s - 0.02, abs=0.005)
    assert emu.physics.pose == reached
    status = robot.read_status()
    assert status.in_position and status.mci is codec.MciState.RUNNING
    assert status.measured_force is not None and len(status.measured_force) == 6
    # 5 mm at 100 mm/s is 50 ms of ramp, plus 20 ms control lag, plus the servo lag
    assert 0.07 < status.controller_time_s < 0.2


@pytest.mark.parametrize("version", codec.VERSIONS)
def test_status_carries_joints_clock_and_fc_active(
    egm_pair: MakePair, version: codec.Version
) -> None:
    """The driver reads the six axes, the controller's clock since 1970 and RW7 fcActive."""
    robot, emu = egm_pair(driver={"version": version}, controller={"version": version})
    before = robot.read_status()
    assert len(before.joints_deg) == 6 and len(before.planned_joints_deg) == 6
    assert robot.read_joints_deg() == before.joints_deg
    epoch = emu.config.clock_epoch_us
    assert before.controller_clock_us is not None
    assert epoch <= before.controller_clock_us < epoch + 1_000_000  # the cell's first second
    robot.move_by(dx_mm=5.0)
    robot.wait_in_position(timeout_s=1.0)
    after = robot.read_status()
    assert after.joints_deg != before.joints_deg
    assert after.controller_clock_us is not None and before.controller_clock_us is not None
    assert after.controller_clock_us - before.controller_clock_us == round(
        (after.controller_time_s - before.controller_time_s) * 1e6)
    assert after.fc_active is (False if version == "rw7" else None)
    assert after.measured_force is not None and len(after.measured_force) == 6


def run_sequence(make: MakePair) -> tuple[float, int, list[Pose]]:
    """Three moves with waits; return simulated time, cycles and the poses reached."""
    robot, emu = make()
    poses = []
    for dz in (-3.0, 2.0, -1.0):
        robot.move_by(dz_mm=dz)
        robot.wait_in_position(timeout_s=1.0, settle_s=0.01)
        poses.append(robot.read_pose())
    poses.append(robot.dwell(0.05))
    return emu.clock.now_s, emu.cycles, poses


def test_lockstep_results_are_fixed_by_the_traffic(egm_pair: MakePair) -> None:
    """Two runs of the same calls give the same simulated times, cycles and poses exactly."""
    assert run_sequence(egm_pair) == run_sequence(egm_pair)


def test_limits_are_refused_before_anything_is_sent(egm_pair: MakePair) -> None:
    """Workspace, step and speed limits raise SafetyStop; no datagram ever carries the target."""
    robot, emu = egm_pair(driver={"limits": {"max_step_mm": 5.0}})
    replies = emu.replies
    with pytest.raises(SafetyStop, match="max_step_mm"):
        robot.move_by(dz_mm=-6.0)
    with pytest.raises(SafetyStop, match="workspace"):
        robot.move_to(Pose(200.0, 0.0, 600.0, HOME.quaternion))
    with pytest.raises(SafetyStop, match="max_speed_mm_s"):
        robot.set_speed(300.0)
    with pytest.raises(ValueError, match="unit length"):
        robot.move_to(Pose(900.0, 0.0, 600.0, (1.0, 1.0, 0.0, 0.0)))
    assert emu.replies == replies  # nothing was sent by the refused calls
    robot.dwell(0.1)
    assert emu.model.planned == HOME and emu.physics.pose == HOME
    assert robot.target == HOME


def test_stop_holds_the_pose(egm_pair: MakePair) -> None:
    """stop() mid-move makes the robot hold near where it was, not go on to the target."""
    robot, _ = egm_pair()
    robot.move_by(dz_mm=-8.0)
    robot.dwell(0.04)
    robot.stop()
    held = robot.target
    assert held is not None and 592.0 < held.z_mm < 600.0
    robot.wait_in_position(timeout_s=1.0, settle_s=0.05)
    reached = robot.read_pose()
    assert np.linalg.norm(reached.position_mm - held.position_mm) <= 0.2
    assert reached.z_mm > 595.0


def test_rw6_rw7_mismatch_is_refused(egm_pair: MakePair) -> None:
    """A driver set for RW6 ignores an RW7 controller's datagrams and says why at the timeout."""
    robot, _ = egm_pair(driver={"version": "rw6"}, controller={"version": "rw7"}, wait=False)
    with pytest.raises(EgmVersionMismatch, match=r"robot\.version = 'rw7'"):
        robot.wait_for_session(0.5)
    assert robot.stats.wrong_version >= 1 and robot.stats.sessions == 0


def test_watchdog_on_the_controllers_messages(egm_pair: MakePair, egm_route: str) -> None:
    """A controller that falls silent ends the wait in LinkTimeout after watchdog_s.

    In process, a closed controller is known at once: LinkError, saying so.
    """
    robot, emu = egm_pair(driver={"watchdog_s": 0.2})
    emu.close()
    expected = (LinkTimeout, "watchdog_s") if egm_route == "udp" else (LinkError, "closed")
    with pytest.raises(expected[0], match=expected[1]):
        robot.dwell(0.1)


@pytest.mark.parametrize(
    ("fault", "counter", "expected"),
    [
        ("lose", "missed", 1),
        ("duplicate", "duplicates", 1),
        ("reorder", "out_of_order", 1),
        ("lose_reply", None, 0),
        ("late_reply", None, 0),
    ],
)
def test_faults_are_counted_and_guidance_goes_on(
    egm_pair: MakePair, fault: str, counter: str | None, expected: int
) -> None:
    """One fault of each kind: the driver counts it and still reaches the target."""
    faults = EgmFaultConfig(**{fault: Fault(1.0, limit=1)}, after_cycles=3)
    robot, emu = egm_pair(emulator={"faults": faults})
    robot.move_by(dz_mm=-2.0)
    robot.wait_in_position(timeout_s=1.0, settle_s=0.02)
    assert emu.faults.fired[fault] == 1
    if counter is not None:
        assert getattr(robot.stats, counter) == expected
    if fault == "reorder":
        assert robot.stats.missed == 1  # k+1 arrived before k


def test_controller_restart_drops_the_target_and_holds(egm_pair: MakePair) -> None:
    """Seqno 0 mid-move: the wait raises GuidanceStopped, the pose is held, moving resumes."""
    faults = EgmFaultConfig(restart=Fault(1.0, limit=1), after_cycles=8)
    robot, _ = egm_pair(emulator={"faults": faults})
    robot.move_by(dz_mm=-4.0)
    with pytest.raises(GuidanceStopped, match="new EGM session"):
        robot.wait_in_position(timeout_s=1.0)
    assert robot.stats.sessions == 2
    assert robot.target == robot.read_pose()
    robot.move_by(dz_mm=-1.0)
    robot.wait_in_position(timeout_s=1.0, settle_s=0.01)


@pytest.mark.udp_only
def test_comm_timeout_ends_guidance_and_the_driver_says_so(egm_pair: MakePair) -> None:
    """A PC silent past CommTimeout: the controller stops and reports it; the driver raises."""
    robot, emu = egm_pair(controller={"comm_timeout_s": 0.1}, emulator={"patience_s": 0.05})
    robot.dwell(0.02)
    assert emu.guidance_stopped.wait(10.0)  # the driver holds its answer: the PC is silent
    with pytest.raises(GuidanceStopped, match="EGM STOPPED"):
        robot.dwell(1.0)
    with pytest.raises(GuidanceStopped):
        robot.move_by(dz_mm=-1.0)


@pytest.mark.udp_only
def test_real_mode_answers_from_a_thread_and_detects_stale_feedback(egm_pair: MakePair) -> None:
    """Lockstep = False: every message is answered at once; silence makes the feedback stale."""
    robot, emu = egm_pair(driver={"lockstep": False, "stale_after_s": 0.02, "watchdog_s": 1.0})
    robot.move_by(dy_mm=3.0)
    robot.wait_in_position(timeout_s=2.0, settle_s=0.02)
    reached = robot.read_pose()
    assert abs(reached.y_mm - 3.0) <= 0.2
    emu.close()
    time.sleep(0.05)  # longer than stale_after_s: what is measured is the age, not a duration
    with pytest.raises(LinkTimeout, match="stale"):
        robot.read_pose()
