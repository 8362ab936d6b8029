"""The twin's arm model is the emulated arm's motion on its tick grid."""

from __future__ import annotations

import math

import numpy as np
import pytest

from forcelearn.devices import Pose
from forcelearn.emulators.physics.arm_motion import ArmMotion, MotionParams
from forcelearn.tools.twin.arm_model import in_position_s, profile

DOWN = (0.0, 1.0, 0.0, 0.0)


def _emulated_s(params: MotionParams, distance: float, phase: float) -> float:
    """Command to in position on the emulator's own arm, s."""
    home = Pose(900.0, 0.0, 0.0, DOWN)
    motion = ArmMotion(params, home)
    begin = (10 + phase) * params.tick_s
    motion.command(Pose(900.0, distance, 0.0, DOWN), begin)
    t = begin
    while not motion.in_position:
        t = (math.floor(t / params.tick_s + 1e-9) + 1) * params.tick_s
        motion.advance_to(t)
    return t - begin


@pytest.mark.parametrize("lag, accel", [(0.01, 1000.0), (0.03, 1000.0), (0.15, 3000.0)])
def test_in_position_time_is_the_emulators_mean(lag: float, accel: float) -> None:
    """Over lengths and command phases: the emulator's mean time, within a tick each."""
    params = MotionParams(lag_s=lag, accel_mm_s2=accel)
    arm = {"start_delay_s": params.start_delay_s, "accel_mm_s2": accel,
           "default_speed_mm_s": params.speed_mm_s, "lag_s": lag}
    rng = np.random.default_rng(1)
    lengths = rng.uniform(0.5, 10.0, 60)
    took = np.array([_emulated_s(params, d, rng.uniform()) for d in lengths])
    error = in_position_s(lengths, arm, params.in_position_mm) - took
    assert abs(error.mean()) < params.tick_s / 4
    assert np.abs(error).max() <= params.tick_s


def test_profile_groups_lengths_and_ends_at_the_target() -> None:
    """One run per distinct length; the tool's share of the path ends at 1."""
    arm = {"accel_mm_s2": 1000.0, "default_speed_mm_s": 100.0, "lag_s": 0.03}
    found = profile(np.array([[5.0, 5.0], [2.0, 0.0]]), arm, 0.1, keep_path=True)
    assert found.lengths_mm.tolist() == [0.0, 2.0, 5.0]
    assert found.share is not None
    assert found.share[:, -1] == pytest.approx(1.0, abs=0.1 / 2.0)
    assert found.ticks[0] == 0.0


@pytest.mark.parametrize("lag, accel, speed", [(0.02, 1000.0, 100.0), (0.15, 600.0, 30.0)])
def test_the_tools_progress_is_the_emulators_mean_over_phases(lag: float, accel: float,
                                                              speed: float) -> None:
    """Where the emulated tool is after its motion began: the model's progress, to 10 um.

    (A pose read scatters by a tick of motion, 0.1-0.4 mm: the mean over 40 phases is the
    model's interpolation to a few um.)
    """
    from forcelearn.tools.twin.arm_model import progress_mm

    params = MotionParams(lag_s=lag, accel_mm_s2=accel, speed_mm_s=speed)
    arm = {"accel_mm_s2": accel, "default_speed_mm_s": speed, "lag_s": lag}
    times = np.array([0.0, 0.03, 0.08, 0.15, 0.3, 0.6, 1.2])  # from the motion's start
    for distance in (0.8, 4.0, 9.5):
        reads = []
        for phase in np.linspace(0.0, 1.0, 40, endpoint=False):
            motion = ArmMotion(params, Pose(900.0, 0.0, 0.0, DOWN))
            begin = (10 + phase) * params.tick_s
            motion.command(Pose(900.0, distance, 0.0, DOWN), begin)
            row = []
            for t in times:
                motion.advance_to(begin + params.start_delay_s + t)
                row.append(motion.pose.y_mm)
            reads.append(row)
        model = progress_mm(np.full(times.size, distance), arm, params.in_position_mm, times)
        assert np.max(np.abs(np.mean(reads, axis=0) - model)) < 0.01, distance


@pytest.mark.parametrize("lag, accel, speed", [
    (0.0128, 316.0, 100.0),  # a slow arm: the tool inside the band before the reference stops
    (0.01, 1000.0, 100.0), (0.03, 1000.0, 100.0), (0.15, 3000.0, 100.0), (0.005, 600.0, 30.0),
])
def test_the_tick_of_in_position_is_the_emulators_own(lag: float, accel: float,
                                                      speed: float) -> None:
    """Every move, shorter than the band too, comes in position on the emulator's own tick.

    The emulated controller reports in position at the first tick where its reference has
    stopped on the target and the tool is inside the band; the profile's whole ticks count
    the same tick from the first tick of motion.
    """
    from forcelearn.tools.twin.tick_grid import whole_ticks

    params = MotionParams(lag_s=lag, accel_mm_s2=accel, speed_mm_s=speed)
    arm = {"accel_mm_s2": accel, "default_speed_mm_s": speed, "lag_s": lag}
    rng = np.random.default_rng(2)
    # lengths on the model's 1 um grouping, so each is run at its own length
    lengths = np.round(np.concatenate([rng.uniform(0.001, 0.12, 12),
                                       rng.uniform(0.12, 12.0, 24)]), 3)
    found = profile(lengths, arm, params.in_position_mm)
    model = whole_ticks(found.ticks[found.inverse])
    first = math.ceil(params.start_delay_s / params.tick_s - 1e-9)  # commanded at 0
    for distance, ticks in zip(lengths, model, strict=True):
        motion = ArmMotion(params, Pose(900.0, 0.0, 0.0, DOWN))
        motion.command(Pose(900.0, float(distance), 0.0, DOWN), 0.0)
        index = first - 1
        while not motion.in_position:
            index += 1
            motion.advance_to(index * params.tick_s)
        assert index - first + 1 == ticks, distance
