"""The foam on a part: the one foam law along the part's normal, under a tool that turns."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from forcelearn.devices import Pose
from forcelearn.emulators.physics.cell import CellPhysics
from forcelearn.emulators.physics.part import Cylinder, Plane
from forcelearn.emulators.physics.part_foam import PartFoam, PartSetup
from forcelearn.emulators.physics.sponge_law import SpongeParams, normal_force_n
from forcelearn.emulators.physics.tool import ToolParams, gravity_wrench

FOAM = SpongeParams(relaxation_ratio=0.0)
CYLINDER = Cylinder((900.0, 0.0, 0.0), (0.0, 1.0, 0.0), 110.0)


def tool_into(normal: np.ndarray) -> tuple[float, float, float, float]:
    """An orientation whose tool z points against ``normal`` (into the part)."""
    z = -normal / np.linalg.norm(normal)
    x = np.cross([0.0, 1.0, 0.0], z)
    turn = Rotation.from_matrix(np.column_stack([x, np.cross(z, x), z]))
    w_last = turn.as_quat()
    return (float(w_last[3]), float(w_last[0]), float(w_last[1]), float(w_last[2]))


@pytest.mark.parametrize("angle_deg", [-25.0, 0.0, 25.0])
def test_the_force_is_the_foam_law_along_the_cylinder_normal(angle_deg: float) -> None:
    """Force = the law's normal force at the foam depth, along the outward normal."""
    normal = np.array([np.sin(np.radians(angle_deg)), 0.0, np.cos(np.radians(angle_deg))])
    depth = 7.0
    skin = np.array(CYLINDER.point_mm) + (CYLINDER.radius_mm + FOAM.thickness_mm) * normal
    foam = PartFoam(PartSetup(CYLINDER), FOAM)
    foam.observe_orientation(tool_into(normal))
    force = foam.contact_force_world_n(skin - depth * normal)
    tip_z = float((skin - depth * normal)[2])
    expected = float(normal_force_n(FOAM, 0.0, depth, tip_z))
    np.testing.assert_allclose(force, expected * normal, rtol=1e-9, atol=1e-9)


def test_a_round_tip_presses_where_its_ball_is_not_where_the_tcp_is() -> None:
    """A tilted ball tip at the same TCP lies lower, so it presses deeper."""
    plane = Plane((0.0, 0.0, 0.0), (0.0, 0.0, 1.0))
    foam = PartFoam(PartSetup(plane, tip_radius_mm=10.0), FOAM)
    tcp = np.array([0.0, 0.0, FOAM.thickness_mm - 2.0])  # 2 mm into the foam's skin
    foam.observe_orientation(tool_into(np.array([0.0, 0.0, 1.0])))
    straight = foam.contact_force_world_n(tcp)[2]
    tilted = Rotation.from_euler("y", 60, degrees=True) * Rotation.from_quat([1.0, 0, 0, 0])
    q = tilted.as_quat()
    foam.observe_orientation((float(q[3]), float(q[0]), float(q[1]), float(q[2])))
    turned = foam.contact_force_world_n(tcp)[2]
    assert straight > 0.0
    assert turned > straight  # the ball's centre drops as the tool tilts: it presses deeper


def test_a_gap_has_no_part() -> None:
    """Inside the cut-away box there is no force; beside it there is."""
    setup = PartSetup(CYLINDER, gap_min_mm=(895.0, -100.0, 0.0), gap_max_mm=(905.0, 100.0, 400.0))
    foam = PartFoam(setup, FOAM)
    top = np.array([900.0, 0.0, 140.0])
    assert not foam.contact_force_world_n(top).any()
    assert foam.contact_force_world_n(top + np.array([20.0, 0.0, 0.0])).any()


def test_the_sensor_reads_the_contact_in_its_frame_plus_the_tools_weight() -> None:
    """Contact along the sensor's -z, plus the tool's weight at the pose."""
    tool = ToolParams()
    foam = PartFoam(PartSetup(CYLINDER), FOAM)
    normal = np.array([np.sin(0.4), 0.0, np.cos(0.4)])
    q = tool_into(normal)
    skin = np.array(CYLINDER.point_mm) + (CYLINDER.radius_mm + FOAM.thickness_mm) * normal
    physics = CellPhysics(foam, Pose(*(skin - 5.0 * normal), q), tool)
    wrench = physics.true_wrench()
    rotation = Rotation.from_quat([q[1], q[2], q[3], q[0]]).as_matrix()
    contact = wrench[:3] - gravity_wrench(tool, rotation)[:3]
    assert contact[0] == pytest.approx(0.0, abs=1e-9)
    assert contact[1] == pytest.approx(0.0, abs=1e-9)
    assert contact[2] < 0.0  # the part pushes back along the tool's -z


def test_a_pass_is_counted_when_the_tool_leaves_the_foam_and_the_state_round_trips() -> None:
    """Leaving the foam after touching it counts a pass; the state round-trips."""
    foam = PartFoam(PartSetup(CYLINDER), FOAM)
    top = np.array([900.0, 0.0, 150.0])
    foam.observe_pose(top - np.array([0.0, 0.0, 5.0]))
    foam.observe_pose(top + np.array([0.0, 0.0, 20.0]))
    assert foam.passes == 1
    other = PartFoam(PartSetup(CYLINDER), FOAM)
    other.load_state_dict(foam.state_dict())
    assert other.state_dict() == foam.state_dict()


def test_beyond_the_parts_wall_there_is_nothing() -> None:
    """Outside a pipe pressed on its inside (the robot's home, say) the tool touches nothing."""
    pipe = Cylinder((900.0, 0.0, 300.0), (0.0, 1.0, 0.0), 150.0, concave=True)
    foam = PartFoam(PartSetup(pipe), FOAM)
    skin_bottom = np.array([900.0, 0.0, 300.0 - 150.0 + FOAM.thickness_mm])
    assert foam.contact_force_world_n(skin_bottom - np.array([0.0, 0.0, 5.0]))[2] > 0.0
    assert not foam.contact_force_world_n(np.array([900.0, 0.0, 600.0])).any()


def test_hysteresis_and_friction_on_a_part_follow_the_law_along_its_normal() -> None:
    """Pressing in loads (1 + h), easing off unloads (1 - h); a slide drags mu N against it."""
    h, mu, depth = 0.2, 0.3, 8.0
    plane = Plane((0.0, 0.0, 0.0), (0.0, 0.0, 1.0))
    foam = PartFoam(PartSetup(plane), SpongeParams(relaxation_ratio=0.0, hysteresis_loss=h,
                                                   friction_coefficient=mu))
    skin = FOAM.thickness_mm
    for z in np.linspace(skin + 5.0, skin - depth, 40):  # press straight in
        foam.observe_pose(np.array([0.0, 0.0, z]))
    pressed = np.array([0.0, 0.0, skin - depth])
    elastic = float(normal_force_n(foam.params, 0.0, depth, pressed[2]))
    force = foam.contact_force_world_n(pressed)
    assert force[2] == pytest.approx(elastic * (1 + h), rel=0.01)
    assert force[0] == force[1] == 0.0  # no slide yet: no friction
    for x in np.linspace(0.0, 20.0, 21):  # slide along +x at that depth
        foam.observe_pose(np.array([x, 0.0, skin - depth]))
    force = foam.contact_force_world_n(np.array([20.0, 0.0, skin - depth]))
    assert force[0] == pytest.approx(-mu * force[2], rel=1e-9) and force[1] == 0.0
    for z in np.linspace(skin - depth - 3.0, skin - depth, 20):  # ease off 3 mm back
        foam.observe_pose(np.array([20.0, 0.0, z]))
    eased = foam.contact_force_world_n(np.array([20.0, 0.0, skin - depth]))
    assert eased[2] == pytest.approx(elastic * (1 - h), rel=0.05)
    again = PartFoam(PartSetup(plane), foam.params)
    again.load_state_dict(foam.state_dict())
    assert again.contact_force_world_n(np.array([20.0, 0.0, skin - depth])).tolist() == \
        eased.tolist()
