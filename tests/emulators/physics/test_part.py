"""Emulated part geometry against closed forms: plane, cylinder, sphere, height map."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from forcelearn.emulators.physics.part import (
    Cylinder,
    Heightmap,
    Plane,
    Sphere,
    _heightmap_distance,
    _heightmap_point,
    contact,
    load_heights,
    tip_centres_mm,
)
from forcelearn.emulators.physics.sponge_law import (
    SpongeParams,
    normal_force_n,
    stiffness_n_per_mm,
)

RNG = np.random.default_rng(20261203)


def _points(n: int = 200, scale: float = 300.0) -> np.ndarray:
    return RNG.uniform(-scale, scale, size=(n, 3))


def test_tilted_plane() -> None:
    """Depth = r + offset - (c - p).n; the surface point is c moved along n onto the plane."""
    normal = np.array([0.3, -0.2, 1.0]) / np.linalg.norm([0.3, -0.2, 1.0])
    plane = Plane((10.0, 20.0, 30.0), (0.3, -0.2, 1.0))
    c = _points()
    got = contact(plane, c, radius_mm=12.0, offset_mm=5.0)
    height = (c - [10.0, 20.0, 30.0]) @ normal
    np.testing.assert_allclose(got.depth_mm, 17.0 - height)
    np.testing.assert_allclose(got.normal, np.broadcast_to(normal, c.shape))
    np.testing.assert_allclose((got.surface_mm - [10.0, 20.0, 30.0]) @ normal, 5.0, atol=1e-9)


def test_sphere_depth_normal_and_surface_point() -> None:
    """Convex: depth = R + r - |c - o|; concave (a bowl): r - (R - |c - o|), normal inward."""
    centre, radius = np.array([5.0, -3.0, 40.0]), 150.0
    c = _points()
    distance = np.linalg.norm(c - centre, axis=1)
    outward = (c - centre) / distance[:, None]
    convex = contact(Sphere(tuple(centre), radius), c, radius_mm=8.0)
    np.testing.assert_allclose(convex.depth_mm, radius + 8.0 - distance)
    np.testing.assert_allclose(convex.normal, outward)
    np.testing.assert_allclose(convex.surface_mm, centre + radius * outward)
    bowl = contact(Sphere(tuple(centre), radius, concave=True), c, radius_mm=8.0)
    np.testing.assert_allclose(bowl.depth_mm, 8.0 - (radius - distance))
    np.testing.assert_allclose(bowl.normal, -outward)


def test_cylinder_pressed_from_outside_and_from_inside() -> None:
    """Distance from the axis d: convex depth R + r - d; concave (inside a pipe) r + d - R."""
    point, axis, radius = np.array([0.0, 100.0, 50.0]), np.array([1.0, 1.0, 0.0]), 80.0
    u = axis / np.linalg.norm(axis)
    c = _points()
    radial = (c - point) - ((c - point) @ u)[:, None] * u
    d = np.linalg.norm(radial, axis=1)
    convex = contact(Cylinder(tuple(point), tuple(axis), radius), c, radius_mm=10.0)
    np.testing.assert_allclose(convex.depth_mm, radius + 10.0 - d)
    np.testing.assert_allclose(convex.normal, radial / d[:, None])
    inside = contact(Cylinder(tuple(point), tuple(axis), radius, concave=True), c, radius_mm=10.0)
    np.testing.assert_allclose(inside.depth_mm, 10.0 + d - radius)
    np.testing.assert_allclose(inside.normal, -radial / d[:, None])
    surface_radius = np.linalg.norm((inside.surface_mm - point) - ((inside.surface_mm - point)
                                    @ u)[:, None] * u, axis=1)
    np.testing.assert_allclose(surface_radius, radius)


def test_a_point_on_the_axis_or_centre_gets_a_defined_normal() -> None:
    """No NaN where the radial direction is undefined: the depth is still exact."""
    got = contact(Cylinder((0.0, 0.0, 0.0), (0.0, 0.0, 1.0), 50.0), np.zeros((1, 3)))
    assert np.all(np.isfinite(got.normal)) and got.depth_mm[0] == pytest.approx(50.0)
    got = contact(Sphere((0.0, 0.0, 0.0), 50.0), np.zeros(3))
    assert np.linalg.norm(got.normal) == pytest.approx(1.0) and got.depth_mm == 50.0


@pytest.mark.parametrize("interpolation", ["linear", "cubic"])
def test_a_heightmap_equal_to_a_plane_is_that_plane(interpolation: str) -> None:
    """Heights h = a u + b v + h0 over a tilted base plane give the tilted plane exactly."""
    base_normal = Rotation.from_euler("xy", [20, -10], degrees=True).apply([0.0, 0.0, 1.0])
    u_axis = np.cross([0.0, 1.0, 0.0], base_normal)
    u_axis /= np.linalg.norm(u_axis)
    v_axis = np.cross(base_normal, u_axis)
    origin, spacing, a, b, h0 = np.array([-200.0, -150.0, 10.0]), 12.5, 0.15, -0.08, 7.0
    grid_u, grid_v = np.arange(33) * spacing, np.arange(25) * spacing
    heights = a * grid_u[:, None] + b * grid_v[None, :] + h0
    part = Heightmap(heights, tuple(origin), spacing, tuple(base_normal), tuple(u_axis),
                     interpolation=interpolation)  # type: ignore[arg-type]
    normal = base_normal - a * u_axis - b * v_axis
    plane = Plane(tuple(origin + h0 * base_normal), tuple(normal))
    local = RNG.uniform([5, 5, -20], [grid_u[-1] - 5, grid_v[-1] - 5, 60], size=(200, 3))
    c = origin + local @ np.array([u_axis, v_axis, base_normal])
    got, expected = contact(part, c, 6.0, 2.0), contact(plane, c, 6.0, 2.0)
    np.testing.assert_allclose(got.depth_mm, expected.depth_mm, atol=1e-8)
    np.testing.assert_allclose(got.normal, expected.normal, atol=1e-10)
    np.testing.assert_allclose(got.surface_mm, expected.surface_mm, atol=1e-8)


def test_a_cubic_heightmap_of_a_sphere_cap_is_near_the_sphere() -> None:
    """Near the surface and a foam's thickness off it, a curved map's distance is the sphere's."""
    radius, spacing = 400.0, 5.0
    grid = np.arange(-100.0, 100.0 + spacing, spacing)
    heights = np.sqrt(radius**2 - grid[:, None] ** 2 - grid[None, :] ** 2)
    part = Heightmap(heights, (grid[0], grid[0], 0.0), spacing, interpolation="cubic")
    sphere = Sphere((0.0, 0.0, 0.0), radius)
    xy = RNG.uniform(-80, 80, size=(100, 2))
    top = np.sqrt(radius**2 - (xy**2).sum(axis=1))
    outward = np.column_stack([xy, top]) / radius
    for above in (RNG.uniform(-5, 5, size=(100, 1)), RNG.uniform(35, 45, size=(100, 1))):
        c = np.column_stack([xy, top]) + above * outward
        got, exact = contact(part, c, offset_mm=40.0), contact(sphere, c, offset_mm=40.0)
        np.testing.assert_allclose(got.depth_mm, exact.depth_mm, atol=0.05)
        assert np.all(np.einsum("ij,ij->i", got.normal, exact.normal) > np.cos(np.radians(0.5)))


@pytest.mark.parametrize("interpolation", ["linear", "cubic"])
def test_one_point_at_a_time_is_the_vectorised_form_bit_for_bit(interpolation: str) -> None:
    """A cell asks for one tip at a time (a faster path): the general form's numbers exactly."""
    grid = np.arange(0.0, 60.0, 5.0)
    heights = 8.0 * np.sin(grid[:, None] / 9.0) + 0.2 * grid[None, :]
    part = Heightmap(heights, (10.0, -20.0, 5.0), 5.0, normal=(0.0, 0.2, 1.0),
                     u_axis=(1.0, 0.0, 0.0), interpolation=interpolation)  # type: ignore[arg-type]
    c = np.column_stack([RNG.uniform(0, 80, 60), RNG.uniform(-40, 50, 60),
                         RNG.uniform(-10, 40, 60)])
    for point in c:
        fast, general = _heightmap_point(part, point), _heightmap_distance(part, point)
        for got, expected in zip(fast, general, strict=True):
            assert np.asarray(got).tobytes() == np.asarray(expected).tobytes()


def test_beyond_the_heightmap_there_is_no_contact() -> None:
    """Outside the grid the depth is -inf: never in contact, whatever the foam law."""
    part = Heightmap(np.zeros((3, 4)), (0.0, 0.0, 0.0), 10.0)
    got = contact(part, np.array([[-1.0, 5.0, -3.0], [5.0, 31.0, -3.0], [5.0, 5.0, -3.0]]))
    assert got.depth_mm[0] == -np.inf and got.depth_mm[1] == -np.inf
    assert got.depth_mm[2] == pytest.approx(3.0)


def test_tip_centres_follow_the_tool_pose() -> None:
    """The tip's centre is r behind the pressing point along the press axis, turned with it."""
    positions = np.array([[100.0, 0.0, 500.0], [0.0, 0.0, 0.0]])
    flipped = Rotation.from_euler("x", 180, degrees=True).as_quat()[[3, 0, 1, 2]]
    quaternions = np.array([[1.0, 0.0, 0.0, 0.0], flipped])
    centres = tip_centres_mm(positions, quaternions, (0.0, 0.0, 150.0), radius_mm=20.0)
    np.testing.assert_allclose(centres, [[100.0, 0.0, 630.0], [0.0, 0.0, -130.0]], atol=1e-9)


def test_a_tilted_tool_presses_where_its_tip_is() -> None:
    """Tilting a roller tool on a flat part moves the contact and changes the depth."""
    plane = Plane((0.0, 0.0, 0.0), (0.0, 0.0, 1.0))
    flange = np.array([[0.0, 0.0, 140.0]])
    down = Rotation.from_euler("x", 180, degrees=True)
    tilted = down * Rotation.from_euler("y", 30, degrees=True)
    depths = []
    for turn in (down, tilted):
        q = turn.as_quat()[[3, 0, 1, 2]]
        centre = tip_centres_mm(flange, q[None, :], (0.0, 0.0, 150.0), radius_mm=25.0)
        depths.append(contact(plane, centre, radius_mm=25.0).depth_mm[0])
    assert depths[0] == pytest.approx(10.0)
    expected_tilted = 25.0 - (140.0 - 125.0 * np.cos(np.radians(30)))
    assert depths[1] == pytest.approx(expected_tilted)


@pytest.mark.parametrize(("make", "reason"), [
    (lambda: Plane((0.0, 0.0, 0.0), (0.0, 0.0, 0.0)), "plane normal"),
    (lambda: Cylinder((0.0, 0.0, 0.0), (0.0, 0.0, 1.0), 0.0), "cylinder radius_mm"),
    (lambda: Cylinder((0.0, 0.0, np.nan), (0.0, 0.0, 1.0), 5.0), "cylinder point_mm"),
    (lambda: Sphere((0.0, 0.0, 0.0), -1.0), "sphere radius_mm"),
    (lambda: Heightmap(np.zeros((3, 3)), (0.0, 0.0, 0.0), 1.0, interpolation="cubic"),
     "at least 4 x 4"),
    (lambda: Heightmap(np.zeros((3, 3)), (0.0, 0.0, 0.0), 1.0, u_axis=(0.0, 0.0, 2.0)),
     "parallel"),
    (lambda: Heightmap(np.zeros((3, 3)), (0.0, 0.0, 0.0), 0.0), "spacing_mm"),
    (lambda: contact(Sphere((0.0, 0.0, 0.0), 1.0), np.zeros(3), radius_mm=-1.0), "radius_mm"),
])
def test_bad_parameters_are_refused(make: object, reason: str) -> None:
    """Every parameter is checked when the part is made, with the field in the message."""
    with pytest.raises(ValueError, match=reason):
        make()  # type: ignore[operator]


def test_heights_from_csv_and_npy(tmp_path: Path) -> None:
    """A grid of heights reads back from CSV (with comments) and .npy alike."""
    heights = RNG.uniform(0, 10, size=(4, 6))
    np.save(tmp_path / "h.npy", heights)
    (tmp_path / "h.csv").write_text("# heights, mm\n" + "\n".join(
        ",".join(repr(float(v)) for v in row) for row in heights))
    np.testing.assert_array_equal(load_heights(tmp_path / "h.npy"), heights)
    np.testing.assert_array_equal(load_heights(tmp_path / "h.csv"), heights)
    with pytest.raises(ValueError, match="cannot read the height map"):
        load_heights(tmp_path / "missing.csv")


def test_the_depth_is_the_foam_laws_compression() -> None:
    """A foam of the sponge's thickness on a sphere: the sponge law's force from the depth.

    The cover's skin is the sphere moved out by the foam's thickness, so pressing
    d into it gives k * d (linear foam) until the tip meets the rigid part, then
    the backing; beyond a height map (d = -inf) the force is 0.
    """
    law = SpongeParams()
    sphere = Sphere((0.0, 0.0, 0.0), 100.0)
    skin = 100.0 + law.thickness_mm
    below_skin = np.array([2.0, 10.0, law.thickness_mm + 1.0])
    centres = np.column_stack([np.zeros(3), np.zeros(3), skin - below_skin])
    where = contact(sphere, centres, offset_mm=law.thickness_mm)
    np.testing.assert_allclose(where.depth_mm, below_skin)
    force = normal_force_n(law, 0.0, where.depth_mm, np.zeros(3))
    k = stiffness_n_per_mm(law, 0.0, 0.0)
    np.testing.assert_allclose(force[:2], k * below_skin[:2])
    assert force[2] == pytest.approx(k * law.thickness_mm + law.backing_n_per_mm)
    beyond = contact(Heightmap(np.zeros((2, 2)), (0.0, 0.0, 0.0), 1.0), np.array([[5.0, 5.0, 0.0]]))
    assert normal_force_n(law, 0.0, beyond.depth_mm, np.zeros(1))[0] == 0.0
