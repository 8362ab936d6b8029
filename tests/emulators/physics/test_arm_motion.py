"""The arm's motion in simulated time: delay, trapezoidal speed, servo lag, band, stop, faults."""

from __future__ import annotations

import math

import pytest

from forcelearn.devices import Pose
from forcelearn.emulators.physics.arm_motion import ArmMotion, MotionParams

DOWN = (0.0, 1.0, 0.0, 0.0)
HOME = Pose(900.0, 0.0, 600.0, DOWN)


def run_until_in_position(motion: ArmMotion, t0: float, limit_s: float = 10.0) -> float:
    """Advance tick by tick; return the first time the motion reports in position."""
    t = t0
    while not motion.in_position:
        t += motion.params.tick_s
        motion.advance_to(t)
        assert t - t0 < limit_s, "never in position"
    return t


def test_instant_profile_is_at_the_target_when_commanded() -> None:
    """instant=True: the pose is the target the moment it is commanded."""
    motion = ArmMotion(MotionParams(instant=True), HOME)
    target = HOME.moved(dz_mm=-50)
    motion.command(target, 0.0)
    assert motion.pose == target and motion.in_position and not motion.moving


def test_long_move_follows_delay_acceleration_and_speed_limit() -> None:
    """No motion before the start delay; speed never above the limit; arrival as a trapezoid."""
    params = MotionParams(lag_s=0.0, start_delay_s=0.05, speed_mm_s=100.0, accel_mm_s2=1000.0)
    motion = ArmMotion(params, HOME)
    motion.command(HOME.moved(dx_mm=100.0), 0.0)
    motion.advance_to(0.048)
    assert motion.pose.x_mm == HOME.x_mm  # still planning
    t, x_before, peak = 0.048, HOME.x_mm, 0.0
    while not motion.in_position:
        t += params.tick_s
        motion.advance_to(t)
        peak = max(peak, (motion.pose.x_mm - x_before) / params.tick_s)
        x_before = motion.pose.x_mm
        assert t < 5.0
    assert peak <= 100.0 + 1e-9
    assert peak == pytest.approx(100.0)
    # delay + distance / speed + speed / accel (accelerate and brake): 0.05 + 1.0 + 0.1 s
    assert t == pytest.approx(1.15, abs=0.02)
    assert motion.pose == HOME.moved(dx_mm=100.0)


def test_servo_lag_delays_in_position_until_within_the_band() -> None:
    """The tool lags the path: in position only once within in_position_mm of the target."""
    quick = ArmMotion(MotionParams(lag_s=0.0), HOME)
    lagging = ArmMotion(MotionParams(lag_s=0.05, in_position_mm=0.1), HOME)
    target = HOME.moved(dz_mm=-5.0)
    for motion in (quick, lagging):
        motion.command(target, 0.0)
    t_quick = run_until_in_position(quick, 0.0)
    t_lag = run_until_in_position(lagging, 0.0)
    # the tool trails the path by at most the whole move (5 mm) when the path ends, and a
    # first-order lag closes that to the 0.1 mm band within lag * ln(50)
    assert 0.05 < t_lag - t_quick <= 0.05 * math.log(50) + 0.004
    assert math.dist(lagging.pose.position_mm, target.position_mm) <= 0.1


def test_motion_does_not_depend_on_how_often_it_is_looked_at() -> None:
    """Advancing in one call or in many small ones gives the same state (fixed tick grid)."""
    a, b = ArmMotion(MotionParams(), HOME), ArmMotion(MotionParams(), HOME)
    for m in (a, b):
        m.command(HOME.moved(dy_mm=7.0, dz_mm=-3.0), 0.013)
    a.advance_to(0.6071)
    t = 0.013
    while t < 0.6071:
        t = min(0.6071, t + 0.0017)
        b.advance_to(t)
    assert a.state_dict() == b.state_dict()


def test_stop_brakes_on_the_path_and_the_rest_point_becomes_the_target() -> None:
    """STOP mid-move: the arm brakes at its acceleration on the path, then is in position."""
    params = MotionParams(lag_s=0.0, start_delay_s=0.0)
    motion = ArmMotion(params, HOME)
    goal = HOME.moved(dx_mm=100.0)
    motion.command(goal, 0.0)
    motion.advance_to(0.3)
    x_at_stop = motion.pose.x_mm
    motion.stop(0.3)
    assert HOME.x_mm < motion.target.x_mm < goal.x_mm
    # brakes from 100 mm/s at 1000 mm/s^2: 5 mm
    assert motion.target.x_mm - x_at_stop == pytest.approx(5.0, abs=0.5)
    t = run_until_in_position(motion, 0.3)
    assert t < 0.5
    assert motion.pose.x_mm == pytest.approx(motion.target.x_mm)


def test_a_robot_that_stops_short_is_never_in_position() -> None:
    """The stall fault: the path ends at a fraction of the way, in position never comes."""
    motion = ArmMotion(MotionParams(), HOME)
    motion.stall_fraction = 0.5
    motion.command(HOME.moved(dz_mm=-10.0), 0.0)
    motion.advance_to(3.0)
    assert not motion.moving
    assert not motion.in_position
    assert motion.pose.z_mm == pytest.approx(HOME.z_mm - 5.0, abs=0.01)


def test_pure_rotation_takes_angle_over_rotation_speed() -> None:
    """Turning 30 deg in place at 60 deg/s takes about 0.5 s (plus the delay and ramps)."""
    params = MotionParams(lag_s=0.0, start_delay_s=0.0)
    motion = ArmMotion(params, HOME)
    c, s = math.cos(math.radians(15)), math.sin(math.radians(15))
    tilted = Pose(HOME.x_mm, HOME.y_mm, HOME.z_mm, (0.0, c, s, 0.0))
    motion.command(tilted, 0.0)
    t = run_until_in_position(motion, 0.0)
    assert 0.5 <= t <= 0.7


def test_state_dict_resumes_mid_move_bit_identically() -> None:
    """Save mid-move, load into a fresh motion: both continue identically."""
    a = ArmMotion(MotionParams(), HOME)
    a.command(HOME.moved(dx_mm=8.0), 0.0)
    a.command(HOME.moved(dx_mm=8.0, dz_mm=-9.0), 0.08)
    a.advance_to(0.1)
    b = ArmMotion(MotionParams(), HOME)
    b.load_state_dict(a.state_dict())
    for m in (a, b):
        m.advance_to(0.9)
    assert a.state_dict() == b.state_dict()
    assert a.pose == b.pose


def test_motion_params_refuse_nonsense() -> None:
    """Zero speed, negative lag or NaN are ValueErrors naming the parameter."""
    with pytest.raises(ValueError, match="speed_mm_s"):
        MotionParams(speed_mm_s=0.0)
    with pytest.raises(ValueError, match="lag_s"):
        MotionParams(lag_s=-0.1)
    with pytest.raises(ValueError, match="tick_s"):
        MotionParams(tick_s=math.nan)
