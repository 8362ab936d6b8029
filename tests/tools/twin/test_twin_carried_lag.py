"""A link's unreported reached poses carry the last move's decaying lag error (twin/arm.py).

The emulated arm's servo lag is linear: the error the tool had when the last move came in
position decays whatever the next move does. With a long lag that error is still there at
the next move's in position and sets the direction the tool creeps in during the burst,
which decides whether a press on a tilted surface slides the roller (friction).
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from forcelearn.devices import Pose
from forcelearn.emulators.physics.arm_motion import ArmMotion, MotionParams
from forcelearn.emulators.physics.cell import CellPhysics
from forcelearn.emulators.physics.sponge import Sponge, SpongeParams
from forcelearn.records import BurstRecord, MoveRecord, StepRecord, TrialRecords
from forcelearn.tools.twin import forward
from forcelearn.tools.twin.arm import reached_in_position_mm
from forcelearn.tools.twin.arrays import to_arrays
from forcelearn.tools.twin.simulate import DOWN

MOTION = MotionParams(lag_s=0.18)
ARM = {"start_delay_s": MOTION.start_delay_s, "accel_mm_s2": MOTION.accel_mm_s2,
       "default_speed_mm_s": MOTION.speed_mm_s, "lag_s": MOTION.lag_s,
       "tick_s": MOTION.tick_s}
SPONGE = SpongeParams(surface_y_mm=0.0, surface_slope=0.105, waviness_mm=0.0,
                      friction_coefficient=0.3, relaxation_ratio=0.0)
"""A surface tilted just past the slide threshold for a press along Y (tan 6 degrees)."""
TARGETS = ((900.0, -3.0, 0.0), (900.0, -1.0, -5.0), (900.0, -3.0, -5.0))
"""Into the foam along -Y, a step down the strip lifting off a little, a press along -Y."""


def _emulated() -> tuple[TrialRecords, list[tuple[float, float, float]],
                         tuple[float, float, float]]:
    """The moves on the emulated arm and sponge, recorded as the computer link does.

    Returns the records (reached = commanded: the link reports none), where the tool was at
    each in position, and the sponge's slide direction during the last move's burst.
    """
    sponge = Sponge(SPONGE)
    start = Pose(900.0, 15.0, 0.0, DOWN)
    physics = CellPhysics(sponge, start)
    motion = ArmMotion(MOTION, start)
    physics.attach_motion(motion)
    tick, now, wait_end = MOTION.tick_s, 0.0, 0.0
    steps, tools = [], []
    for index, target in enumerate(TARGETS):
        motion.command(Pose(*target, DOWN), now)
        t = now
        while True:
            t = (math.floor(t / tick + 1e-9) + 1) * tick
            physics.advance_to(t)
            if motion.in_position:
                break
        pose = motion.pose
        tools.append((pose.x_mm, pose.y_mm, pose.z_mm))
        now = t + 0.087  # the link's poll and the burst
        physics.advance_to(now)
        move = MoveRecord(target, target, wait_end, t, t)
        burst = BurstRecord(10.0, 0.1, 10.0, 10.0, 5, t + 0.06, 0.024, 10.0)
        steps.append(StepRecord(0, index, "step", move, burst))
        wait_end = now
    return TrialRecords(0, steps), tools, sponge.slide_direction


def test_unreported_reached_pose_carries_the_last_moves_lag_error() -> None:
    """The modelled pose at the press's in position is the emulated tool's, off the line too."""
    records, tools, _ = _emulated()
    data = to_arrays([records])
    reached = reached_in_position_mm(data, ARM, MOTION.in_position_mm)[0]
    true = np.array(tools)
    # the press runs along Y: the step's error left along Z is what the model must carry
    left_z = true[2, 2] - TARGETS[2][2]
    assert abs(left_z) > 1e-4
    assert abs(reached[2, 2] - true[2, 2]) < 0.2 * abs(left_z)


def test_a_press_creeps_and_slides_as_the_emulated_sponge_has_it() -> None:
    """The slide direction at the press's burst: the emulator's, not a slide up the tilt."""
    records, _, emulated_slide = _emulated()
    data = to_arrays([records])
    data = dataclasses.replace(
        data, reached=reached_in_position_mm(data, ARM, MOTION.in_position_mm))
    state = forward.contact_state(data, SPONGE, ARM)
    assert emulated_slide[2] != 0.0
    assert np.sign(state.slide_z[0, 2]) == np.sign(emulated_slide[2])
    assert abs(state.slide_y[0, 2] - emulated_slide[1]) < 0.02
