"""Kinematic model of the emulated arm: joint angles, refusals, settings."""

from __future__ import annotations

import math

import numpy as np
import pytest

from forcelearn.devices import IDENTITY_QUATERNION, Pose
from forcelearn.emulators.physics.arm import (
    HOME,
    TOOL_DOWN,
    ArmConfig,
    check_target,
    joint_angles_deg,
)

CONFIG = ArmConfig()


def _forward_mm(config: ArmConfig, joints: tuple[float, ...]) -> np.ndarray:
    """Independent forward kinematics of J1..J3 (the inverse of the model)."""
    j1, j2, j3 = (math.radians(a) for a in joints[:3])
    upper = math.pi / 2 - j2  # from horizontal
    r = config.upper_arm_mm * math.cos(upper) + config.forearm_mm * math.cos(upper + j3)
    h = config.upper_arm_mm * math.sin(upper) + config.forearm_mm * math.sin(upper + j3)
    return np.array([r * math.cos(j1), r * math.sin(j1), h + config.shoulder_height_mm])


@pytest.mark.parametrize("xyz", [(900, 0, 600), (700, 300, 900), (1200, -400, 100)])
def test_joint_angles_reproduce_the_position_through_forward_kinematics(xyz) -> None:
    """J1..J3 put the tool back where it was asked to be."""
    joints = joint_angles_deg(CONFIG, Pose(*xyz, TOOL_DOWN))
    assert joints is not None
    np.testing.assert_allclose(_forward_mm(CONFIG, joints), xyz, atol=1e-6)


def test_wrist_angles_of_known_orientations() -> None:
    """Identity gives J5 = 0; tool down J5 = 180; a 90 deg turn about z shows in J6."""
    assert joint_angles_deg(CONFIG, Pose(900, 0, 600))[3:] == pytest.approx((0, 0, 0))
    assert joint_angles_deg(CONFIG, HOME)[4] == pytest.approx(180.0)
    turn = (math.cos(math.pi / 4), 0.0, 0.0, math.sin(math.pi / 4))
    assert joint_angles_deg(CONFIG, Pose(900, 0, 600, turn))[3:] == pytest.approx((0, 0, 90))


@pytest.mark.parametrize(
    ("pose", "kind"),
    [
        (Pose(900, 0, 1500, TOOL_DOWN), "workspace"),
        (Pose(1500, 800, 1400, TOOL_DOWN), "joint"),  # in the box, out of reach
        (Pose(900, 0, 600, (1.0, 0.1, 0.0, 0.0)), "orientation"),
        (Pose(math.nan, 0, 600, TOOL_DOWN), "workspace"),
    ],
)
def test_targets_outside_the_limits_are_refused(pose: Pose, kind: str) -> None:
    """Each limit has its own kind of refusal; a good target passes."""
    refusal = check_target(CONFIG, pose)
    assert refusal is not None
    assert refusal[0] == kind
    assert check_target(CONFIG, HOME) is None
    assert check_target(CONFIG, Pose(900, 0, 600, IDENTITY_QUATERNION)) is None


def test_joint_range_refuses_a_reachable_target() -> None:
    """A reachable target whose J2 (-44 deg) is outside a narrowed range is refused."""
    limits = ((-170, 170), (-30, 110), (-165, -5), (-180, 180), (0, 180), (-180, 180))
    refusal = check_target(ArmConfig(joint_limits_deg=limits), Pose(350, 0, 1350, TOOL_DOWN))
    assert refusal is not None
    assert refusal[0] == "joint"
    assert "J2" in refusal[1]
    assert check_target(CONFIG, Pose(350, 0, 1350, TOOL_DOWN)) is None


def test_arm_config_rejects_inconsistent_settings() -> None:
    """An empty workspace or a negative lag is a ValueError naming the field."""
    with pytest.raises(ValueError, match="workspace_min_mm"):
        ArmConfig(workspace_min_mm=(0, 0, 0), workspace_max_mm=(0, 1, 1))
    with pytest.raises(ValueError, match="lag_s"):
        ArmConfig(lag_s=-1.0)
