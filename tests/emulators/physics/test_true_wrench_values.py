"""``CellPhysics.true_wrench_values`` (what the JR3 model reads) is ``true_wrench`` as floats."""

from __future__ import annotations

import random
from typing import Any

import numpy as np
import pytest

from forcelearn.devices import Pose
from forcelearn.emulators.physics.arm_motion import ArmMotion, MotionParams
from forcelearn.emulators.physics.cell import CellPhysics, NoContact
from forcelearn.emulators.physics.sponge import Sponge, SpongeParams, surface_y_mm
from forcelearn.emulators.physics.tool import ToolParams

DOWN = (0.0, 1.0, 0.0, 0.0)
TILTED = (0.9238795325112867, 0.0, 0.3826834323650898, 0.0)
TOOL = ToolParams(mass_kg=1.2, com_mm=(3.0, -2.0, 70.0), contact_point_mm=(1.0, 0.5, 160.0))
MATERIALS = {
    "default": SpongeParams(),
    "hysteretic, stiffening, sliding": SpongeParams(hysteresis_loss=0.3, stiffening_exponent=1.3,
                                                    friction_coefficient=0.4),
}


@pytest.mark.parametrize("name", sorted(MATERIALS))
def test_values_are_the_array_as_floats_through_presses_and_turns(name: str) -> None:
    """Every read of a pressing, sliding, turning arm: the values equal the array's ``tolist``."""
    params = MATERIALS[name]
    sponge = Sponge(params)
    surface = surface_y_mm(params, 0, -40.0)
    start = Pose(0.0, surface + 20.0, -40.0, DOWN)
    cell = CellPhysics(sponge, start, tool=TOOL)
    motion = ArmMotion(MotionParams(), start)
    cell.attach_motion(motion)
    rng = random.Random(3)
    t, reads, contacts = 0.0, 0, 0
    for move in range(30):
        depth = rng.uniform(-3.0, 6.0) if move % 5 else 20.0
        quaternion = TILTED if move % 7 == 3 else DOWN  # a turn changes the weight's wrench
        motion.command(Pose(0.0, surface - depth, -40.0 - 2.5 * move, quaternion), t)
        for _ in range(rng.randint(3, 30)):
            t += rng.choice((0.0001285, 0.001, 0.004, 0.013))
            cell.advance_to(t)
            first_values = rng.random() < 0.5  # either read first: one cache serves both
            values = cell.true_wrench_values() if first_values else None
            expected = tuple(cell.true_wrench().tolist())
            if values is None:
                values = cell.true_wrench_values()
            assert values == expected and [type(v) for v in values] == [float] * 6
            assert [v.hex() for v in values] == [v.hex() for v in expected]  # signed zeros too
            reads += 1
            contacts += any(sponge.contact_force_world_values(cell._position))
    assert reads > 300 and contacts > 50


def test_an_environment_without_values_gives_its_array_as_floats() -> None:
    """Free space (``NoContact``: no ``contact_force_world_values``): the tool's weight."""
    cell = CellPhysics(NoContact(), Pose(0.0, 0.0, 0.0, TILTED), tool=TOOL)
    assert cell.true_wrench_values() == tuple(cell.true_wrench().tolist())
    assert any(cell.true_wrench_values())
    cell.tool = ToolParams()  # a new tool: the cached wrench is of the old one
    assert cell.true_wrench_values() == tuple(cell.true_wrench().tolist())


def test_sponge_values_are_its_force_array_as_floats() -> None:
    """``Sponge.contact_force_world_values`` is ``contact_force_world_n``'s ``tolist``."""
    params = SpongeParams(friction_coefficient=0.3)
    sponge = Sponge(params)
    rng = np.random.default_rng(5)
    for _ in range(200):
        y = surface_y_mm(params, sponge.passes, -40.0) - float(rng.uniform(-2.0, 8.0))
        point = (0.0, y, float(rng.uniform(-60.0, -20.0)))
        sponge.relaxing_mm = float(rng.uniform(0.0, 1.0))
        sponge.slide_direction = tuple(rng.uniform(-1.0, 1.0, 3).tolist())
        values = sponge.contact_force_world_values(point)
        assert values == tuple(sponge.contact_force_world_n(np.array(point)).tolist())


class _OwnLaw(Sponge):
    """A subclass with its own force law (as the twin's tests build foams outside the family)."""

    def contact_force_world_n(self, position_mm: Any) -> np.ndarray:
        return np.array([0.0, 7.5 + self._penetration_mm(position_mm), 0.0])


def test_an_overridden_or_wrapped_force_law_is_what_the_values_read() -> None:
    """A subclass's law and a recorder wrapped on the object are asked, as ``true_wrench`` asks."""
    params = SpongeParams()
    point = Pose(0.0, surface_y_mm(params, 0, -40.0) - 2.0, -40.0, DOWN)
    own = CellPhysics(_OwnLaw(params), point, tool=TOOL)
    assert own.true_wrench_values() == tuple(own.true_wrench().tolist())
    assert own.environment.contact_force_world_values(own._position)[1] > 7.5

    sponge = Sponge(params)
    cell = CellPhysics(sponge, point, tool=TOOL)
    asked: list[object] = []
    original = sponge.contact_force_world_n

    def recorded(position_mm: Any) -> np.ndarray:
        asked.append(position_mm)
        return original(position_mm)

    sponge.contact_force_world_n = recorded  # type: ignore[method-assign]
    assert cell.true_wrench_values() == tuple(cell.true_wrench().tolist())
    assert len(asked) == 2


def test_a_wrapped_true_wrench_is_what_the_values_read() -> None:
    """fault_inject wraps ``true_wrench`` on the physics: the JR3 model's read goes through it."""
    cell = CellPhysics(NoContact(), Pose(0.0, 0.0, 0.0, DOWN), tool=TOOL)
    cell.true_wrench = lambda: np.arange(6.0)  # type: ignore[method-assign]
    assert cell.true_wrench_values() == (0.0, 1.0, 2.0, 3.0, 4.0, 5.0)
