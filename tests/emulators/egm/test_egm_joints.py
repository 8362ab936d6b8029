"""The six axes of the emulated EGM arm: forward and inverse kinematics, axis ranges."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from forcelearn.devices import Pose, quaternion_to_matrix
from forcelearn.emulators.egm.joints import limit_violation, tool_pose
from forcelearn.emulators.physics.arm import HOME, ArmConfig, joint_angles_deg

ARM = ArmConfig()


def test_forward_kinematics_of_a_hand_computed_pose() -> None:
    """Upper arm vertical, elbow bent 90 deg down: tip one forearm out, shoulder + upper arm up."""
    pose = tool_pose(ARM, (0.0, 0.0, -90.0, 0.0, 90.0, 0.0))
    assert pose.position_mm == pytest.approx([850.0, 0.0, 750.0 + 710.0], abs=1e-9)
    # Z-Y-Z wrist (0, 90, 0): the tool's z axis points along the base x axis
    assert quaternion_to_matrix(pose.quaternion)[:, 2] == pytest.approx([1.0, 0.0, 0.0], abs=1e-12)
    yawed = tool_pose(ARM, (90.0, 0.0, -90.0, 0.0, 90.0, 0.0))
    assert yawed.position_mm == pytest.approx([0.0, 850.0, 1460.0], abs=1e-9)


def test_home_pose_joints_are_degrees_within_the_ranges() -> None:
    """The cell's home (900, 0, 600) mm, tool down: J1 = 0, wrist at J5 = 180 deg."""
    joints = joint_angles_deg(ARM, HOME)
    assert joints is not None and len(joints) == 6
    assert joints[0] == pytest.approx(0.0) and joints[4] == pytest.approx(180.0)
    assert limit_violation(ARM, joints) is None
    assert tool_pose(ARM, joints).position_mm == pytest.approx(HOME.position_mm, abs=1e-9)


@settings(max_examples=60, deadline=None)
@given(
    st.tuples(
        st.floats(-160.0, 160.0), st.floats(-60.0, 100.0), st.floats(-160.0, -10.0),
        st.floats(-170.0, 170.0), st.floats(5.0, 175.0), st.floats(-170.0, 170.0),
    )
)
def test_inverse_kinematics_inverts_forward_kinematics(
    joints: tuple[float, float, float, float, float, float],
) -> None:
    """Away from the wrist singularities, IK(FK(j)) = j and FK(IK(pose)) = pose."""
    pose = tool_pose(ARM, joints)
    yaw = math.radians(joints[0])
    if pose.x_mm * math.cos(yaw) + pose.y_mm * math.sin(yaw) < 1.0:
        return  # tool behind or on the base axis: reached with J1 turned 180 deg (or any J1)
    back = joint_angles_deg(ARM, pose)
    assert back is not None
    assert back == pytest.approx(joints, abs=1e-6)
    again = tool_pose(ARM, back)
    assert again.position_mm == pytest.approx(pose.position_mm, abs=1e-6)
    assert abs(float(np.dot(again.quaternion, pose.quaternion))) == pytest.approx(1.0, abs=1e-9)


def test_out_of_reach_and_out_of_range_are_reported() -> None:
    """A pose beyond the two links has no joints; each axis range is checked by number."""
    assert joint_angles_deg(ARM, Pose(3000.0, 0.0, 750.0, HOME.quaternion)) is None
    assert limit_violation(ARM, (0.0, 0.0, -90.0, 0.0, 90.0, 0.0)) is None
    reason = limit_violation(ARM, (0.0, 120.0, -90.0, 0.0, 90.0, 0.0))
    assert reason is not None and "J2" in reason and "-70..110" in reason
    assert limit_violation(ARM, (0.0, 0.0, 0.0, 0.0, 90.0, 0.0)) is not None  # J3 -165..-5
    assert "6 finite" in (limit_violation(ARM, (0.0,) * 5) or "")
    assert "6 finite" in (limit_violation(ARM, (0.0, math.nan, -90.0, 0.0, 90.0, 0.0)) or "")
    with pytest.raises(ValueError, match="6 finite"):
        tool_pose(ARM, (0.0, 0.0, -90.0))
