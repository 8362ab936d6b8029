"""The passes counted from the surface at the recorded poses, as the emulated sponge counts."""

from __future__ import annotations

from forcelearn.emulators.physics import sponge_law as law
from forcelearn.emulators.physics.arm import ArmConfig
from forcelearn.emulators.physics.sponge import Sponge
from forcelearn.emulators.physics.sponge_law import SpongeParams
from forcelearn.records import BurstRecord, MoveRecord, StepRecord, TrialRecords
from forcelearn.tools.twin.arrays import to_arrays
from forcelearn.tools.twin.pass_count import surface_passes
from forcelearn.tools.twin.setup import base_arm

SPONGE = SpongeParams(relaxation_ratio=0.8, relaxation_time_s=0.9)
ARM = base_arm()  # the emulator's defaults


def _step(trial: int, stage: str, y_mm: float, force_n: float | None, t: float,
          reached_mm: float | None = None) -> StepRecord:
    reached = y_mm if reached_mm is None else reached_mm
    move = MoveRecord((0.0, y_mm, 0.0), (0.0, reached, 0.0), t, t + 0.1, t + 0.2)
    burst = None if force_n is None else BurstRecord(force_n, 0.05, force_n, force_n, 16,
                                                     0.2, t + 0.2, force_n)
    return StepRecord(trial, 0, stage, move, burst)


def _trial(trial: int, surface: float) -> tuple[TrialRecords, list[float]]:
    """A press eased off 0.2 mm (still in a relaxed foam, reading ~0 N), pressed again."""
    plan = [(10.0, 0.0), (surface - 3.0, 6.0), (surface - 0.2, 0.0), (surface - 2.0, 4.0),
            (surface + 12.0, None)]
    steps = [_step(trial, "approach" if k == 0 else "retreat" if k == 4 else "step", y, f,
                   100.0 * trial + k) for k, (y, f) in enumerate(plan)]
    return TrialRecords(trial, steps), [y for y, _ in plan]


def test_a_relaxed_foam_eased_off_but_still_pressed_ends_no_pass() -> None:
    """Counted where the tool is, not from the force: one pass a trial, as the sponge counts."""
    surface = float(law.surface_y_mm(SPONGE, 0.0, 0.0))
    trials = [_trial(k, surface) for k in range(3)]
    data = to_arrays([t for t, _ in trials])
    sponge = Sponge(SPONGE)
    expected = []
    for _, ys in trials:
        row = []
        for y in ys:
            row.append(sponge.passes)
            sponge.observe_pose((0.0, y, 0.0))
        expected.append(row)
    (counted,) = surface_passes([data], SPONGE, ARM)
    assert counted.passes[:, :5].tolist() == expected
    assert expected[-1][0] == 2  # one pass a trial
    assert data.passes[-1, 0] > expected[-1][0]  # the force's count took the ease-off for one


def test_an_identification_is_counted_apart_on_the_fresh_foam() -> None:
    """Rows of the identification's trial start from 0 passes; the run's go on after theirs."""
    surface = float(law.surface_y_mm(SPONGE, 0.0, 0.0))
    identification = to_arrays([_trial(-2, surface)[0]])
    run = to_arrays([_trial(k, surface)[0] for k in range(2)])
    ident, counted = surface_passes([identification, run], SPONGE, ARM, apart=-2)
    assert ident.passes[0, :5].tolist() == [0] * 5
    assert counted.passes[:, 0].tolist() == [0, 1]  # not after the identification's pass


def test_a_retreat_in_position_inside_the_foam_that_closes_out_of_it_is_a_pass() -> None:
    """In position within the band short of a target just out of the foam, then out: a pass.

    The arm reports in position up to the band short of its target and the tool goes on
    toward it with the servo lag; the sponge counts the pass where the tool leaves the foam,
    before the next move (an identification's small retreats: hidden cell 09 of seed 1).
    """
    surface = float(law.surface_y_mm(SPONGE, 0.0, 0.0))
    band = ArmConfig().in_position_mm  # the emulated arm's in-position band
    steps = [_step(0, "approach", 10.0, 0.0, 0.0), _step(0, "step", surface - 2.0, 5.0, 1.0),
             _step(0, "step", surface + 0.6 * band, 0.0, 2.0, surface - 0.4 * band),
             _step(0, "step", surface - 2.0, 5.0, 3.0), _step(0, "retreat", 10.0, None, 4.0)]
    data = to_arrays([TrialRecords(0, steps)])
    sponge = Sponge(SPONGE)
    expected = []
    for step in steps:  # the tool at its target by the next move: the lag closed in 1 s
        expected.append(sponge.passes)
        sponge.observe_pose(step.move.reached_mm)
        sponge.observe_pose(step.move.commanded_mm)
    (counted,) = surface_passes([data], SPONGE, ARM)
    assert counted.passes[0, :5].tolist() == [0, 0, 0, 1, 1]
    assert counted.passes[0, :5].tolist() == expected
