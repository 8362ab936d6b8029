"""The motion ticks in one call to the sponge (``Sponge.tick``) are the two calls, to the bit."""

from __future__ import annotations

import math
import random

import pytest

from forcelearn.devices import Pose
from forcelearn.emulators.physics.arm_motion import ArmMotion, MotionParams
from forcelearn.emulators.physics.cell import CellPhysics
from forcelearn.emulators.physics.sponge import Sponge, SpongeParams, relaxation_step, surface_y_mm

DOWN = (0.0, 1.0, 0.0, 0.0)

MATERIALS = {
    "default": SpongeParams(),
    "hysteretic, stiffening, sliding": SpongeParams(hysteresis_loss=0.3, stiffening_exponent=1.3,
                                                    friction_coefficient=0.4),
    "no relaxation": SpongeParams(relaxation_ratio=0.0),
}


def _run(params: SpongeParams, fused: bool, batched: bool = False) -> list[tuple[object, ...]]:
    """Press, slide and lift off through several passes; the sponge's state after every move."""
    sponge = Sponge(params)
    surface = surface_y_mm(params, 0, -40.0)
    start = Pose(0.0, surface + 20.0, -40.0, DOWN)
    cell = CellPhysics(sponge, start)
    motion = ArmMotion(MotionParams(), start)
    cell.attach_motion(motion)
    if not fused:
        cell._ticked = None  # the route of an environment without tick(): two calls per tick
    if not batched:
        cell._batched = None  # the route of an environment without ticks(): a call per tick
    rng = random.Random(7)
    t, states = 0.0, []
    for move in range(40):
        depth = rng.uniform(-3.0, 6.0) if move % 5 else 20.0  # every 5th move lifts off
        target = Pose(0.0, surface - depth, -40.0 - 2.5 * move, DOWN)
        motion.command(target, t)
        for _ in range(rng.randint(3, 40)):  # reads between ticks and across many ticks
            t += rng.choice((0.001, 0.004, 0.013, 0.05))
            cell.advance_to(t)
            states.append((sponge.passes, sponge.relaxing_mm, sponge._foam_mm,
                           sponge.hysteresis_state, tuple(sponge.slide_direction),
                           tuple(cell.true_wrench().tolist())))
    return states


@pytest.mark.parametrize("name", sorted(MATERIALS))
def test_fused_ticks_are_the_two_calls_to_the_bit(name: str) -> None:
    """Passes, relaxing part, foam depth, hysteresis, slide and wrench equal after every read."""
    fused, split = _run(MATERIALS[name], True), _run(MATERIALS[name], False)
    assert max(state[0] for state in fused) >= 3  # passes were finished on ticks
    assert any(state[1] != 0.0 for state in fused) == (MATERIALS[name].relaxation_ratio != 0.0)
    assert [repr(s) for s in fused] == [repr(s) for s in split]


@pytest.mark.parametrize("name", sorted(MATERIALS))
def test_batched_ticks_are_the_two_calls_to_the_bit(name: str) -> None:
    """The arm's ticks then the sponge's in one call each (``advance_keys``, ``Sponge.ticks``)."""
    batched, split = _run(MATERIALS[name], True, True), _run(MATERIALS[name], False)
    assert max(state[0] for state in batched) >= 3
    assert [repr(s) for s in batched] == [repr(s) for s in split]


def test_batched_ticks_match_on_a_path_that_turns_and_crosses_the_strip() -> None:
    """Turns, moves across the strip's ends and reads between ticks, to the bit."""
    def run(batched: bool) -> list[str]:
        params = SpongeParams()
        sponge = Sponge(params)
        surface = surface_y_mm(params, 0, params.z_top_mm - 5.0)
        start = Pose(0.0, surface + 3.0, params.z_top_mm + 8.0, DOWN)
        cell = CellPhysics(sponge, start)
        motion = ArmMotion(MotionParams(), start)
        cell.attach_motion(motion)
        if not batched:
            cell._batched = None
        rng = random.Random(11)
        t, states = 0.0, []
        for _ in range(60):
            z = rng.uniform(params.z_bottom_mm - 10.0, params.z_top_mm + 10.0)
            angle = rng.choice((0.0, 0.0, 0.2, -0.3))
            q = (math.cos(angle / 2), math.sin(angle / 2), 0.0, 0.0)
            motion.command(Pose(0.0, surface - rng.uniform(-2.0, 5.0), z, q), t)
            for _ in range(rng.randint(1, 30)):
                t += rng.choice((0.0005, 0.004, 0.009, 0.2))
                cell.advance_to(t)
                states.append(repr((sponge.passes, sponge.relaxing_mm, sponge._foam_mm,
                                    cell.pose, cell.true_wrench().tolist())))
        assert sponge.passes >= 3
        return states

    assert run(True) == run(False)


def test_the_fused_route_is_taken_for_the_sponge() -> None:
    """A sponge gets one call per tick (the route the test above compares)."""
    assert CellPhysics(Sponge())._ticked is not None
    assert CellPhysics(Sponge())._batched is not None


def test_the_kept_relaxation_terms_are_relaxation_step_to_the_bit() -> None:
    """``Sponge._evolve_at`` against ``relaxation_step`` on random states, changes and steps."""
    rng = random.Random(3)
    for _ in range(2000):
        params = SpongeParams(relaxation_time_s=rng.choice((0.4, 0.05, 3.0)))
        sponge = Sponge(params)
        q, old, depth = rng.uniform(-2, 2), rng.uniform(0, 8), rng.uniform(0, 8)
        dt = rng.choice((0.004, 0.001, 0.25, rng.uniform(1e-6, 2.0)))
        sponge.relaxing_mm, sponge._foam_mm = q, old
        sponge._evolve_at(depth, dt)
        expected = relaxation_step(params, q, depth - old, dt)
        assert math.copysign(1.0, sponge.relaxing_mm) == math.copysign(1.0, expected)
        assert sponge.relaxing_mm == expected


def test_a_hook_on_move_tool_still_sees_every_tick() -> None:
    """A tool (fault_inject's Truth, step_timeline) that wraps ``_move_tool`` gets the old route."""
    start = Pose(0.0, 30.0, -40.0, DOWN)
    cell = CellPhysics(Sponge(), start)
    motion = ArmMotion(MotionParams(lag_s=0.0), start)
    cell.attach_motion(motion)
    seen: list[object] = []
    move = cell._move_tool

    def moved(key: object) -> None:
        move(key)  # type: ignore[arg-type]
        seen.append(key)

    cell._move_tool = moved  # type: ignore[method-assign]
    motion.command(start.moved(dy_mm=-10.0), 0.0)
    cell.advance_to(1.0)
    assert len(seen) > 20 and seen[-1] == motion.tool_key
