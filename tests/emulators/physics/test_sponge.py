"""The sponge: force law, variation along Z, drift with passes, pass counting, state."""

from __future__ import annotations

import numpy as np
import pytest

from forcelearn.devices import Pose
from forcelearn.emulators.physics.cell import CellPhysics
from forcelearn.emulators.physics.sponge import (
    Sponge,
    SpongeParams,
    contact_force_n,
    stiffness_n_per_mm,
    surface_y_mm,
)

P = SpongeParams()
DESIRED_N = 19.61  # the paper's 2 kgf


def _at(y: float, z: float) -> np.ndarray:
    return np.array([0.0, y, z])


def test_no_force_outside_the_sponge() -> None:
    """Above the surface and beyond either end of the strip the force is zero."""
    z = -40.0
    above = surface_y_mm(P, 0, z) + 0.1
    assert not contact_force_n(P, 0, _at(above, z)).any()
    assert not contact_force_n(P, 0, _at(-10.0, P.z_top_mm + 1)).any()
    assert not contact_force_n(P, 0, _at(-10.0, P.z_bottom_mm - 1)).any()


def test_force_is_stiffness_times_depth_mostly_along_plus_y() -> None:
    """Inside the foam |F| = k(z) * depth and the sponge pushes the tool back along +Y."""
    z = -40.0
    for depth in (1.0, 5.0, 12.0):
        force = contact_force_n(P, 0, _at(surface_y_mm(P, 0, z) - depth, z))
        assert np.linalg.norm(force) == pytest.approx(stiffness_n_per_mm(P, 0, z) * depth)
        assert force[1] > 0.95 * np.linalg.norm(force)
        assert force[0] == 0.0


def test_backing_is_much_stiffer_than_the_foam() -> None:
    """Pressing 1 mm past the foam's thickness adds the backing's stiffness."""
    z = -40.0
    surface = surface_y_mm(P, 0, z)
    at_thickness = np.linalg.norm(contact_force_n(P, 0, _at(surface - P.thickness_mm, z)))
    past = np.linalg.norm(contact_force_n(P, 0, _at(surface - P.thickness_mm - 1, z)))
    assert past - at_thickness == pytest.approx(P.backing_n_per_mm, rel=1e-6)


def test_desired_force_is_reached_with_a_few_mm_steps() -> None:
    """On the paper's 20 steps of -5 mm, 19.61 N needs 5-20 mm depth; 3 mm moves it >2 N."""
    for z in np.arange(0.0, -100.1, -5.0):
        k = stiffness_n_per_mm(P, 0, z)
        assert 5.0 < DESIRED_N / k < 20.0
        assert 3.0 * k > 2.0


def test_surface_and_stiffness_vary_along_the_travel() -> None:
    """At fixed Y the force changes by several newtons over the 100 mm trajectory."""
    zs = np.arange(0.0, -100.1, -5.0)
    y = surface_y_mm(P, 0, 0.0) - 8.0
    forces = np.array([np.linalg.norm(contact_force_n(P, 0, _at(y, z))) for z in zs])
    assert forces.max() - forces.min() > 5.0
    assert len({round(stiffness_n_per_mm(P, 0, z), 6) for z in zs}) > 10


def test_initial_force_falls_with_passes_as_in_fig_14() -> None:
    """Starting 4 mm deep at the same pose, the initial force falls 8.6 N -> 3.6 N in 240 passes."""
    start = _at(surface_y_mm(P, 0, 0.0) - 4.0, 0.0)
    initial = [np.linalg.norm(contact_force_n(P, n, start)) for n in range(0, 241, 20)]
    assert np.all(np.diff(initial) < 0)
    assert 8.0 < initial[0] < 10.0
    assert 3.0 < initial[-1] < 4.5


def test_passes_are_counted_when_the_tool_leaves_after_contact() -> None:
    """Through the cell, each in-and-out of the sponge counts one pass; free moves count none."""
    sponge = Sponge()
    cell = CellPhysics(sponge, Pose(0.0, 50.0, 0.0))
    for _ in range(3):
        cell.set_pose(Pose(0.0, 50.0, 0.0))
        cell.set_pose(Pose(0.0, 50.0, -50.0))  # free move, no contact
        for z in np.arange(0.0, -100.1, -5.0):
            cell.set_pose(Pose(0.0, -8.0, z))
        cell.set_pose(Pose(0.0, -8.0, P.z_bottom_mm - 5))  # run off the end
    assert sponge.passes == 3


def test_state_round_trip_restores_the_force() -> None:
    """A restored sponge gives the same force as the one saved, mid-pass included."""
    sponge = Sponge(passes=37)
    sponge.observe_pose(_at(-5.0, -20.0))
    state = sponge.state_dict()
    other = Sponge()
    other.load_state_dict(state)
    point = _at(-6.0, -30.0)
    assert np.array_equal(other.contact_force_world_n(point), sponge.contact_force_world_n(point))
    other.observe_pose(_at(50.0, -30.0))
    assert other.passes == 38


@pytest.mark.parametrize("field", ["stiffness_n_per_mm", "thickness_mm", "set_passes"])
def test_params_refuse_non_positive_values(field: str) -> None:
    """A zero stiffness, thickness or time constant is a configuration error naming the field."""
    with pytest.raises(ValueError, match=field):
        SpongeParams(**{field: 0.0})
