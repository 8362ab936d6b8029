"""The arm's kinematics moved to :mod:`forcelearn.emulators.physics.arm` (every robot kind's).

Kept so that old imports resolve; new code imports from the physics module.
"""

from forcelearn.emulators.physics.arm import (
    HOME,
    QUATERNION_TOLERANCE,
    TOOL_DOWN,
    ArmConfig,
    check_target,
    joint_angles_deg,
)

__all__ = [
    "HOME", "QUATERNION_TOLERANCE", "TOOL_DOWN", "ArmConfig", "check_target", "joint_angles_deg",
]
