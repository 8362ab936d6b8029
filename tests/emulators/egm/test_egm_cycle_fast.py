"""The EGM controller's per-cycle shortcuts against the computations they stand for."""

from __future__ import annotations

import math
import random

from forcelearn.devices import Pose
from forcelearn.emulators.egm.controller import EgmControllerConfig, EgmControllerModel
from forcelearn.emulators.egm.target_checks import TargetChecks
from forcelearn.emulators.physics.arm import HOME, ArmConfig, joint_angles_deg
from forcelearn.emulators.physics.cell import CellPhysics

ARM = ArmConfig()
DOWN = HOME.quaternion


def _random_pose(rng: random.Random) -> Pose:
    """Poses in and out of the workspace and the arm's reach, odd quaternions, non-finite values."""
    x, y, z = rng.uniform(0.0, 1800.0), rng.uniform(-900.0, 900.0), rng.uniform(-300.0, 1600.0)
    q: tuple[float, float, float, float] = DOWN
    kind = rng.random()
    if kind < 0.1:
        x = rng.choice((math.nan, math.inf, -math.inf))
    elif kind < 0.2:
        q = (0.0, 1.0005, 0.0, 0.0) if rng.random() < 0.5 else (0.0, 1.002, 0.0, 0.0)
    elif kind < 0.4:
        a = rng.uniform(-math.pi, math.pi)
        q = (math.cos(a / 2), 0.0, math.sin(a / 2), 0.0)  # tilts that break J5's range or not
    elif kind < 0.5:
        q = (math.nan, 1.0, 0.0, 0.0)
    return Pose(x, y, z, q)


def test_the_written_out_check_is_the_worded_one() -> None:
    """Refusal (its text) and axes of the fast check equal the step-by-step check's."""
    checks = TargetChecks(ARM, (300.0, -800.0, -200.0), (1500.0, 800.0, 1400.0))
    rng = random.Random(5)
    passed = 0
    for _ in range(20_000):
        pose = _random_pose(rng)
        expected = checks._refusal_and_joints(pose)
        assert repr(checks.refusal_and_joints(pose)) == repr(expected)
        passed += expected[0] is None
    assert 1_000 < passed < 19_000  # both kinds of answer were compared


def test_the_reported_axes_found_late_are_those_found_every_cycle() -> None:
    """The latest reachable pose's axes, whatever unreachable poses came after it."""
    model = EgmControllerModel(EgmControllerConfig(), CellPhysics(pose=HOME))
    rng = random.Random(9)
    expected = model._feedback_joints
    for step in range(3_000):
        reachable = rng.random() < 0.7
        pose = (HOME.moved(rng.uniform(-50, 50), rng.uniform(-50, 50), rng.uniform(-50, 50))
                if reachable else Pose(5000.0, 0.0, rng.uniform(0, 100), DOWN))
        model._moved(step * 0.004, pose)
        joints = joint_angles_deg(ARM, pose)
        expected = expected if joints is None else joints
        if rng.random() < 0.2:  # asked now and then (an EgmRobot built)
            assert model._feedback_joints == expected
    assert model._feedback_joints == expected
    assert model.state_dict()["feedback_joints"] == list(expected)
