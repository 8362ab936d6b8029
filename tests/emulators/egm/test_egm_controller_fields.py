"""The emulated controller beside poses: joints, clock, fcActive, speedRef, joint/pose mode."""

from __future__ import annotations

import itertools

import pytest

from forcelearn.devices import Pose
from forcelearn.emulators.egm.controller import (
    DEFAULT_CLOCK_EPOCH_US,
    EgmControllerConfig,
    EgmControllerModel,
)
from forcelearn.emulators.egm.joints import tool_pose
from forcelearn.emulators.egm.servo import ServoParams
from forcelearn.emulators.physics.arm import HOME, ArmConfig, joint_angles_deg
from forcelearn.emulators.physics.cell import CellPhysics
from forcelearn.protocols.egm import codec

ARM = ArmConfig()
PERIOD = 0.004


def model_of(**kw: object) -> EgmControllerModel:
    """A controller at HOME with the private lag servo."""
    return EgmControllerModel(EgmControllerConfig(**kw), CellPhysics(pose=HOME))  # type: ignore[arg-type]


def cycle(model: EgmControllerModel, k: int, sensor: codec.SensorMessage | None = None,
          ) -> codec.RobotMessage:
    """Run cycle ``k``: read ``sensor`` (if any), return the decoded EgmRobot."""
    t = k * PERIOD
    if sensor is not None:
        model.apply_sensor(codec.encode_sensor(sensor, model.config.version), t)
    return codec.decode_robot(model.robot_datagram(t), model.config.version)


def test_joints_and_clock_in_every_message() -> None:
    """feedBack/planned joints are the arm's six axes; the clock is µs since 1970 from the epoch."""
    model = model_of(clock_epoch_us=1_700_000_000_123_456)
    first = cycle(model, 0)
    home = joint_angles_deg(ARM, HOME)
    assert first.joints_deg == home and first.planned_joints_deg == home
    assert first.time_us == 1_700_000_000_123_456
    assert first.planned_time_us == 1_700_000_000_123_456 + 20_000  # + the 20 ms control lag
    target = HOME.moved(dx_mm=20.0)
    seen = [cycle(model, k, codec.SensorMessage(k, 0, target)) for k in range(1, 60)]
    assert seen[-1].time_us == 1_700_000_000_123_456 + 59 * 4000
    assert seen[-1].planned_joints_deg == joint_angles_deg(ARM, target)
    assert seen[-1].feedback is not None
    assert seen[-1].joints_deg == joint_angles_deg(ARM, seen[-1].feedback)
    assert seen[-1].joints_deg != home
    assert cycle(model_of(), 0).time_us == DEFAULT_CLOCK_EPOCH_US


@pytest.mark.parametrize("active", [False, True])
def test_rw7_fc_active_and_raw_force(active: bool) -> None:
    """RW7: fcActive follows the controller's force control; the force is sent either way (p.36)."""
    message = cycle(model_of(version="rw7", force_control_active=active), 0)
    assert message.fc_active is active
    assert message.measured_force is not None and len(message.measured_force) == 6


def ramp_end_x(speed_ref: bool) -> float:
    """Feedback x after 0.4 s of a 50 mm/s planned ramp along x (with or without speedRef)."""
    model = model_of(servo=ServoParams(control_lag_s=0.020, time_constant_s=0.010))
    message = cycle(model, 0)
    for k in range(1, 101):
        planned = HOME.moved(dx_mm=50.0 * k * PERIOD)
        ref = (50.0, 0.0, 0.0, 0.0, 0.0, 0.0) if speed_ref else None
        message = cycle(model, k, codec.SensorMessage(k, 0, planned, speed_ref=ref))
    assert message.feedback is not None
    return message.feedback.x_mm


def test_speed_ref_feed_forward_removes_the_servo_lag() -> None:
    """Manual p.26, speed = k (ref - pos) + speedRef: k = 1/tau, the ramp is led by v tau."""
    gained = ramp_end_x(True) - ramp_end_x(False)
    assert gained == pytest.approx(50.0 * 0.010, rel=1e-3)


def test_joint_mode_follows_planned_joints() -> None:
    """EGMSetupUC with the Joint switch: the arm goes to planned.joints, echoed as planned."""
    model = model_of(mode="joint")
    home = joint_angles_deg(ARM, HOME)
    assert home is not None
    goal = (home[0] + 5.0, home[1] + 3.0, *home[2:])
    message = cycle(model, 0)
    for k in range(1, 80):
        message = cycle(model, k, codec.SensorMessage(k, 0, None, planned_joints_deg=goal))
    assert message.mci is codec.MciState.RUNNING
    assert message.planned_joints_deg == goal
    assert message.joints_deg == pytest.approx(goal, abs=1e-6)
    assert message.feedback is not None
    assert message.feedback.position_mm == pytest.approx(tool_pose(ARM, goal).position_mm)


def test_joint_mode_refuses_joints_out_of_range_with_a_motion_error() -> None:
    """A J2 beyond its range stops EGM (MCI_ERROR) and the arm holds."""
    model = model_of(mode="joint")
    home = joint_angles_deg(ARM, HOME)
    assert home is not None
    bad = (home[0], 130.0, *home[2:])
    message = cycle(model, 1, codec.SensorMessage(1, 0, None, planned_joints_deg=bad))
    assert message.mci is codec.MciState.ERROR
    assert message.feedback == HOME


@pytest.mark.parametrize("mode", ["pose", "joint"])
def test_the_other_modes_field_is_counted_and_the_reference_kept(mode: str) -> None:
    """Only the other mode's position data: no motion, still running, counted in wrong_mode."""
    model = model_of(mode=mode)
    home = joint_angles_deg(ARM, HOME)
    assert home is not None
    other = (
        codec.SensorMessage(1, 0, None, planned_joints_deg=(home[0] + 10.0, *home[1:]))
        if mode == "pose" else codec.SensorMessage(1, 0, HOME.moved(dx_mm=10.0))
    )
    message = cycle(model, 1, other)
    for k in range(2, 30):
        message = cycle(model, k)
    assert message.mci is codec.MciState.RUNNING
    assert message.feedback == HOME
    assert model.wrong_mode == 1 and model.targets_read == 0


def test_pose_mode_refuses_a_pose_out_of_the_arms_reach() -> None:
    """Inside the workspace box but beyond the links: a motion error, as a joint limit is."""
    model = model_of()
    far = Pose(1500.0, 800.0, 1400.0, HOME.quaternion)
    message = cycle(model, 1, codec.SensorMessage(1, 0, far))
    assert message.mci is codec.MciState.ERROR


@pytest.mark.parametrize("bad", [{"mode": "cartesian"}, {"clock_epoch_us": -1},
                                 {"clock_epoch_us": True}, {"clock_epoch_us": 1.5}])
def test_bad_settings_are_refused(bad: dict[str, object]) -> None:
    """A mode other than pose/joint, or an epoch that is not whole µs >= 0."""
    with pytest.raises(ValueError):
        EgmControllerConfig(**bad)  # type: ignore[arg-type]


def test_checkpoint_keeps_joints_and_wrong_mode() -> None:
    """A restored controller sends the same joints and keeps its counters."""
    model = model_of()
    cycle(model, 1, codec.SensorMessage(1, 0, None, planned_joints_deg=(1.0,) * 6))
    cycle(model, 2, codec.SensorMessage(2, 0, HOME.moved(dx_mm=5.0)))
    restored = model_of()
    restored.load_state_dict(model.state_dict())
    assert restored.planned_joints == model.planned_joints and restored.wrong_mode == 1


def test_utilization_is_the_speed_over_the_latest_cycle_and_survives_a_restore() -> None:
    """utilizationRate: the feedback's distance over the cycle before / the period, of 1000 mm/s.

    Found only when an EgmRobot reports it; a restore (which keeps no speed) reports the
    speed found before it, as a controller that never computed it lazily would.
    """
    model = model_of(max_speed_mm_s=1000.0)
    target = HOME.moved(dx_mm=20.0)
    seen = [cycle(model, k, codec.SensorMessage(k, 0, target)) for k in range(1, 40)]
    moving = [m for m in seen[1:] if m.utilization_pct]
    assert len(moving) > 10
    for before, now in itertools.pairwise(seen):
        assert before.feedback is not None and now.feedback is not None
        step = ((now.feedback.x_mm - before.feedback.x_mm) ** 2
                + (now.feedback.y_mm - before.feedback.y_mm) ** 2
                + (now.feedback.z_mm - before.feedback.z_mm) ** 2) ** 0.5
        assert now.utilization_pct == pytest.approx(min(100.0, 100.0 * step / PERIOD / 1000.0))
    state = model.state_dict()
    moved = model.move_to(40 * PERIOD)  # a cycle whose EgmRobot is not built, then the restore
    model.load_state_dict(state)
    again = codec.decode_robot(codec.encode_robot(model._message(39 * PERIOD), "rw7"), "rw7")
    assert again.utilization_pct == pytest.approx(
        min(100.0, 100.0 * _dist(moved, seen[-1].feedback) / PERIOD / 1000.0))


def _dist(a: Pose, b: Pose | None) -> float:
    assert b is not None
    return float(((a.x_mm - b.x_mm) ** 2 + (a.y_mm - b.y_mm) ** 2 + (a.z_mm - b.z_mm) ** 2) ** 0.5)
