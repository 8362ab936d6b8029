"""The ramp's cheaper arithmetic gives the bits of the array arithmetic it replaces."""

from __future__ import annotations

import math
import random
import struct

import numpy as np

from forcelearn.devices import Pose, blend_poses
from forcelearn.drivers.egm import ramp

QUATERNIONS = [
    (0.0, 1.0, 0.0, 0.0), (-0.0, 1.0, 0.0, -0.0), (0.5, 0.5, 0.5, 0.5),
    (0.7071067811865476, 0.0, 0.7071067811865475, 0.0), (0.0, 0.9999999, 0.0, 0.0),
]


def _array_step(pose: Pose, target: Pose, max_mm: float, max_deg: float) -> Pose:
    """step_toward as it was: numpy's norm, the angle computed, blend_poses."""
    if pose == target and max_mm >= 0.0 and max_deg >= 1e-3 and ramp.finite_pose(pose):
        return target
    distance = float(np.linalg.norm(target.position_mm - pose.position_mm))
    turn = ramp._angle_deg(pose.quaternion, target.quaternion)
    if distance <= max_mm and turn <= max_deg:
        return target
    fraction = min(max_mm / distance if distance > 0 else 1.0, max_deg / turn if turn > 0 else 1.0)
    return blend_poses(pose, target, fraction)


def _bits(pose: Pose) -> bytes:
    return struct.pack("7d", pose.x_mm, pose.y_mm, pose.z_mm, *pose.quaternion)


def test_step_toward_and_blend_are_the_array_arithmetic_to_the_bit() -> None:
    """Random ramps (mostly one orientation, signed zeros, tiny and large steps) agree bitwise."""
    rng = random.Random(0)
    for _ in range(5000):
        qa = (rng.choice(QUATERNIONS) if rng.random() < 0.8
              else tuple(rng.uniform(-1, 1) for _ in range(4)))
        qb = qa if rng.random() < 0.7 else rng.choice(QUATERNIONS)
        a = Pose(rng.uniform(300, 1500), rng.uniform(-800, 800), rng.uniform(-200, 1400), qa)
        b = Pose(a.x_mm + rng.uniform(-5, 5) * 10 ** rng.randint(-6, 1), a.y_mm,
                 a.z_mm + rng.uniform(-1, 1), qb)
        max_mm = rng.choice([0.4, 0.1, 1e-3, 50.0])
        assert _bits(ramp.step_toward(a, b, max_mm, 0.18)) == _bits(_array_step(a, b, max_mm, 0.18))
        fraction = rng.random()
        assert _bits(ramp.blend(a, b, fraction)) == _bits(blend_poses(a, b, fraction))


def test_blend_of_non_finite_orientations_is_blend_poses() -> None:
    """An infinite or NaN quaternion goes the array way (inf - inf is not zero)."""
    for q in [(math.inf, 0.0, 0.0, 0.0), (math.nan, 1.0, 0.0, 0.0)]:
        a, b = Pose(900.0, 0.0, 600.0, q), Pose(901.0, 0.0, 600.0, q)
        got, want = ramp.blend(a, b, 0.5), blend_poses(a, b, 0.5)
        assert _bits(got) == _bits(want)


def test_angle_deg_kept_answer_is_the_computed_one() -> None:
    """The kept angle is returned only for equal orientations; a zero's sign changes nothing."""
    q, r = (0.0, 1.0, 0.0, 0.0), (0.0, 0.9998, 0.0199987, 0.0)
    first = ramp.angle_deg(q, r)
    assert ramp.angle_deg((-0.0, 1.0, 0.0, -0.0), r) == first == ramp._angle_deg(q, r)
    assert ramp.angle_deg(r, r) == ramp._angle_deg(r, r)
    assert math.isinf(ramp.angle_deg((math.nan, 1.0, 0.0, 0.0), r))
