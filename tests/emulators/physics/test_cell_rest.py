"""The arm's at-rest jump without its tick callback (``CellPhysics.rest_to``) is ``advance_to``."""

from __future__ import annotations

import random

import pytest

from forcelearn.devices import Pose
from forcelearn.emulators.physics.arm_motion import ArmMotion, MotionParams, PoseKey
from forcelearn.emulators.physics.cell import CellPhysics
from forcelearn.emulators.physics.sponge import Sponge, SpongeParams, surface_y_mm

DOWN = (0.0, 1.0, 0.0, 0.0)

MATERIALS = {
    "default": SpongeParams(),
    "hysteretic, stiffening, sliding": SpongeParams(hysteresis_loss=0.3, stiffening_exponent=1.3,
                                                    friction_coefficient=0.4),
}


def _run(params: SpongeParams, resting: bool) -> tuple[list[str], int, int]:
    """Presses and dwells read at EGM-like steps; every state, and how often rest_to did it."""
    sponge = Sponge(params)
    surface = surface_y_mm(params, 0, -40.0)
    start = Pose(0.0, surface + 20.0, -40.0, DOWN)
    cell = CellPhysics(sponge, start)
    motion = ArmMotion(MotionParams(), start)
    cell.attach_motion(motion)
    rng = random.Random(11)
    t, states, rested, moved = 0.0, [], 0, 0
    for move in range(25):
        depth = rng.uniform(-3.0, 6.0) if move % 5 else 20.0
        motion.command(Pose(0.0, surface - depth, -40.0 - 2.5 * move, DOWN), t)
        for _ in range(rng.randint(40, 160)):  # the move, then a dwell at rest
            t += rng.choice((0.004, 0.004, 0.004, 0.001, 0.012))
            if resting and cell.rest_to(t):
                rested += 1
            else:
                moved += 1
                cell.advance_to(t)
            states.append(repr((motion.tick_index, motion.state_dict(), sponge.passes,
                                sponge.relaxing_mm, sponge._foam_mm, sponge.hysteresis_state,
                                tuple(cell.true_wrench().tolist()), cell.pose)))
    return states, rested, moved


@pytest.mark.parametrize("name", sorted(MATERIALS))
def test_rest_to_is_advance_to_where_it_jumps(name: str) -> None:
    """The arm, the sponge (relaxing part, passes, hysteresis) and the wrench after every read."""
    jumped, rested, moved = _run(MATERIALS[name], True)
    plain, _, _ = _run(MATERIALS[name], False)
    assert rested > 500 and moved > 300  # both routes were taken
    assert jumped == plain


def test_rest_to_declines_other_routes() -> None:
    """No motion, a hooked ``_move_tool`` or an environment without ``tick``: nothing done."""
    cell = CellPhysics(Sponge(), Pose(0.0, 50.0, -40.0, DOWN))
    assert not cell.rest_to(1.0)
    cell.attach_motion(ArmMotion(MotionParams(), cell.pose))
    assert cell.rest_to(1.0) and cell.motion is not None and cell.motion.tick_index == 250
    cell._move_tool = cell._move_tool  # type: ignore[method-assign]  # a hook's wrapper
    assert not cell.rest_to(2.0) and cell.motion.tick_index == 250


def test_the_arm_pose_is_one_object_while_the_tool_stays() -> None:
    """:attr:`ArmMotion.pose`: the same object at rest, a new one (of the new values) once moved."""
    start = Pose(0.0, 50.0, -40.0, DOWN)
    motion = ArmMotion(MotionParams(), start)
    first = motion.pose
    assert first == start and motion.pose is first
    motion.advance_to(1.0)
    assert motion.pose is first  # at rest: the ticks jumped, the tool not moved
    motion.command(start.moved(dz_mm=5.0), 1.0)
    motion.advance_to(1.2)
    moved = motion.pose
    x, y, z = motion._tool
    assert moved is not first and moved == Pose(x, y, z, motion._tool_q) != first


def _pressed_at_rest(batched: bool) -> tuple[CellPhysics, Sponge, ArmMotion]:
    """A cell whose arm pressed 4 mm into the default foam and now rests (relaxing)."""
    params = SpongeParams()
    sponge = Sponge(params)
    surface = surface_y_mm(params, 0, -40.0)
    cell = CellPhysics(sponge, Pose(0.0, surface + 5.0, -40.0, DOWN))
    motion = ArmMotion(MotionParams(), cell.pose)
    cell.attach_motion(motion)
    if not batched:
        cell._batched = None  # the per-tick route
    motion.command(Pose(0.0, surface - 4.0, -40.0, DOWN), 0.0)
    cell.advance_to(1.5)
    assert cell.at_rest() and sponge.relaxing_mm > 0.0
    return cell, sponge, motion


def test_rest_through_takes_the_ticks_as_runs(monkeypatch: pytest.MonkeyPatch) -> None:
    """``rest_through`` on a batched foam: its ticks in runs (no ``tick`` each), the same state."""
    rng = random.Random(5)
    times, t = [], 1.5
    for _ in range(400):  # EGM cycles, some two ticks long, some within the tick
        t += rng.choice((0.004, 0.004, 0.004, 0.008, 0.0))
        times.append(t)

    def state(cell: CellPhysics, sponge: Sponge, motion: ArmMotion) -> str:
        return repr((motion.tick_index, sponge.relaxing_mm, sponge._foam_mm, sponge.passes,
                     tuple(cell.true_wrench().tolist())))

    plain = _pressed_at_rest(batched=False)
    for chunk in (times[:150], times[150:151], times[151:]):
        plain[0].rest_through(chunk)
    runs = _pressed_at_rest(batched=True)
    calls = []
    monkeypatch.setattr(Sponge, "tick", lambda *a: calls.append(a))  # not asked on this route
    for chunk in (times[:150], times[150:151], times[151:]):
        runs[0].rest_through(chunk)
    assert not calls
    assert state(*runs) == state(*plain)
    assert runs[2].tick_index == 375 + round((times[-1] - 1.5) / 0.004)


def test_ticks_seen_is_ticks_then_observe_pose_run_by_run() -> None:
    """``Sponge.ticks_seen``: each run's ticks, then the pose seen again, as one by one.

    Presses in and out of the default foam (passes end: the merged route restores
    and replays) and within it (no pass ends: one ``ticks`` call), rest ticks of
    other spans between; every state equal to ``tick`` per key and ``observe_pose``.
    """
    params = SpongeParams()
    surface = surface_y_mm(params, 0, -40.0)
    rng = random.Random(3)
    down = (1.0, 0.0, 0.0, 0.0)

    def path(lift: bool) -> list[tuple[list[PoseKey], float, tuple[float, float, float] | None]]:
        runs: list[tuple[list[PoseKey], float, tuple[float, float, float] | None]] = []
        y, z = surface + 2.0, -40.0
        for step in range(300):
            target = surface - 4.0 if (step // 40) % 2 == 0 or not lift else surface + 3.0
            y += 0.25 * (target - y)
            z -= 0.05
            keys: list[PoseKey] = [(0.0, y, z, down)] * rng.choice((1, 1, 2))
            runs.append((keys, 0.004, (0.0, y, z) if rng.random() < 0.8 else None))
            if rng.random() < 0.1:
                runs.append(([keys[-1]], 0.004 * rng.choice((2, 3)), None))
        return runs

    for lift in (False, True):
        runs = path(lift)
        merged, plain = Sponge(params), Sponge(params)
        start: PoseKey = (0.0, surface + 2.0, -40.0, down)
        last = merged.ticks_seen(runs, start)
        before = start
        for keys, dt, seen in runs:
            for key in keys:
                moved = key != before
                before = key if moved else before
                plain.tick((before[0], before[1], before[2]), dt, moved)
            if seen is not None:
                plain.observe_pose(seen)
        assert merged.passes == plain.passes and (merged.passes > 0) == lift
        assert merged.state_dict() == plain.state_dict() and last == before
