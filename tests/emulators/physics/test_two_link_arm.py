"""The §4 cell: geometry, start force, kinematics and the servo."""

import math

import numpy as np
import pytest

from forcelearn.emulators.physics.two_link_arm import (
    ContourGeometry,
    TwoLinkContourCell,
    forward_kinematics,
    inverse_kinematics,
    normal_force_n,
)
from forcelearn.errors import ConfigError


def test_start_pose_presses_with_the_papers_0_7212_newton() -> None:
    """θ = (45°, −45°) gives exactly 0.7212 N on the 100 N/m surface."""
    cell = TwoLinkContourCell()
    assert cell.reset() == (45.0, -45.0)
    assert cell.force_n() == pytest.approx(0.7212, abs=1e-12)
    assert cell.tip_m() == pytest.approx((1.0 / math.sqrt(2) + 0.8, 1.0 / math.sqrt(2)))


def test_the_whole_45_step_path_stays_inside_the_partitioned_ranges() -> None:
    """Tracking 1 N for 45 cm keeps θ1 in [30, 60]° and θ2 in [−75, −15]° with margin."""
    g = ContourGeometry()
    cx, cy = g.centre_m
    radius = g.radius_m - 1.0 / g.stiffness_n_per_m
    start = math.radians(g.normal_angle_deg)
    for k in range(46):
        angle = start + k * 0.01 / radius
        t1, t2 = inverse_kinematics(g, cx + radius * math.cos(angle), cy + radius * math.sin(angle))
        assert 30.0 + 5.0 < t1 < 60.0 - 5.0
        assert -75.0 + 5.0 < t2 < -15.0 - 5.0
        assert normal_force_n(g, *forward_kinematics(g, t1, t2)) == pytest.approx(1.0)


def test_force_is_stiffness_times_penetration_and_zero_out_of_contact() -> None:
    """Moving 5 mm along the normal into the disc adds 0.5 N; far away there is none."""
    g = ContourGeometry()
    tip = forward_kinematics(g, 45.0, -45.0)
    normal = np.array([math.cos(math.radians(160)), math.sin(math.radians(160))])
    deeper = np.array(tip) - 0.005 * normal
    assert normal_force_n(g, *deeper) == pytest.approx(0.7212 + 0.5)
    assert normal_force_n(g, 0.5, 0.5) == 0.0


def test_inverse_kinematics_inverts_forward_kinematics() -> None:
    """IK(FK(θ)) = θ on the elbow-down branch."""
    g = ContourGeometry()
    for t1, t2 in [(45.0, -45.0), (31.0, -70.0), (58.0, -16.0)]:
        assert inverse_kinematics(g, *forward_kinematics(g, t1, t2)) == pytest.approx((t1, t2))
    with pytest.raises(ValueError, match="reach"):
        inverse_kinematics(g, 3.0, 0.0)


def test_servo_is_ideal_by_default_and_lags_when_configured() -> None:
    """Ideal servo reaches the command; lag 0.5 reaches half the way per step."""
    cell = TwoLinkContourCell()
    assert cell.move(46.0, -44.0) == (46.0, -44.0)
    lagging = TwoLinkContourCell(ContourGeometry(servo_lag=0.5))
    assert lagging.move(46.0, -44.0) == pytest.approx((45.5, -44.5))


@pytest.mark.parametrize(
    "kwargs", [{"servo_lag": 1.0}, {"stiffness_n_per_m": 0.0}, {"start_force_n": 1000.0}]
)
def test_bad_geometry_is_refused(kwargs: dict) -> None:
    """Impossible parameters raise ConfigError."""
    with pytest.raises(ConfigError):
        ContourGeometry(**kwargs)
