"""The pass count from the records: a pass ends only after the tool rose."""

from __future__ import annotations

from forcelearn.records import BurstRecord, MoveRecord, StepRecord, TrialRecords
from forcelearn.tools.twin.arrays import passes_before


def _step(trial: int, stage: str, y_mm: float, force_n: float | None) -> StepRecord:
    move = MoveRecord((0.0, y_mm, 0.0), (0.0, y_mm, 0.0), 0.0, 0.1, 0.2)
    burst = None if force_n is None else BurstRecord(force_n, 0.05, force_n, force_n, 16,
                                                     0.2, 0.01, force_n)
    return StepRecord(trial, 0, stage, move, burst)


def test_a_free_reading_no_higher_than_the_last_contact_ends_no_pass() -> None:
    """Pressed as deep or deeper, a burst reading ~0 N (a zero's step): the same pass."""
    first = TrialRecords(0, [
        _step(0, "approach", 10.0, 0.0),  # the trial's zero, in free space
        _step(0, "step", 5.0, 5.0),  # contact
        _step(0, "step", 3.0, 9.0),  # deeper
        _step(0, "step", 3.0, 0.05),  # as deep, reads ~0: the zero stepped, still in the foam
        _step(0, "step", 2.5, 6.0),  # deeper still
        _step(0, "retreat", 10.0, None),
    ])
    second = TrialRecords(1, [_step(1, "approach", 10.0, 0.0), _step(1, "step", 5.0, 5.0),
                              _step(1, "step", 6.0, 0.0),  # rose, reads free space: left
                              _step(1, "retreat", 10.0, None)])
    third = TrialRecords(2, [_step(2, "approach", 10.0, 0.0)])
    passes = passes_before([first, second, third], noise_n=0.05)
    assert passes[0] == [0] * 6
    assert passes[1] == [1, 1, 1, 2]  # left at the free-space burst above the touch
    assert passes[2] == [2]


def test_a_probe_easing_off_in_weak_contact_ends_no_pass() -> None:
    """Easing off at a shallow depth the foam still pushes 0.2-0.5 N: the same pass.

    The probe's re-reads as it eases off (16 samples, noise 0.11 N), as the emulated sponge
    read them on hidden cell 15 of seed 3 while the tool stayed in the foam (0.4-0.6 N true):
    under the 0.5 N contact floor, but many sigmas above the zero. The pass ends when the
    next point starts from the retract plane (its first burst reads free space).
    """
    point = TrialRecords(-1, [
        _step(-1, "probe", 16.0, 0.0),  # the point's zero, in free space
        _step(-1, "probe", 0.0, 2.85),  # contact
        _step(-1, "probe", -1.3, 7.5),  # pressed
        _step(-1, "probe", 0.2, 0.46),  # eased off: weak contact
        _step(-1, "probe", 0.2, 1.11),  # the same pose after the dwell: the foam recovered
        _step(-1, "probe", 0.45, 0.21),  # eased off further, still in the foam
        _step(-1, "probe", 0.45, 0.36),
        _step(-1, "probe", 16.0, None),  # back to the retract plane
    ])
    following = TrialRecords(-1, [_step(-1, "probe", 16.0, 0.0), _step(-1, "probe", 16.0, 0.0)])
    passes = passes_before([point, following], noise_n=0.11)
    assert passes[0] == [0] * 8  # the pass ends with the last move, back to the retract plane
    assert passes[1] == [1, 1]


def test_a_contact_read_where_a_pass_seemed_to_end_revokes_it() -> None:
    """A near-0 N read easing off, then the same pose after the dwell reads the foam: one pass.

    A hysteretic foam eased off reads near 0 N on its easing-off branch and recovers over
    the dwell (hidden cell 04 of seed 3: 0.34 N, then 1.91 N, the tool in the foam).
    """
    point = TrialRecords(-1, [
        _step(-1, "probe", 14.0, 0.0),  # the point's zero
        _step(-1, "probe", -2.6, 4.2),  # contact
        _step(-1, "probe", -1.6, 0.2),  # eased off: reads ~0, within the noise
        _step(-1, "probe", -1.6, 1.9),  # the same pose after the dwell: the foam
        _step(-1, "probe", -0.7, 0.05),  # eased off further: free
        _step(-1, "probe", 14.0, None),
    ])
    passes = passes_before([point, TrialRecords(-1, [_step(-1, "probe", 14.0, 0.0)])],
                           noise_n=0.2)
    assert passes[0] == [0, 0, 0, 0, 0, 1]
    assert passes[1] == [1]


def test_backing_off_to_where_free_space_was_read_ends_a_pass() -> None:
    """The probe backs off (no burst) above a Y that read free on its approach, presses again.

    The tool left the foam and came back: two passes (hidden cell 10 of seed 3's probe).
    """
    point = TrialRecords(-1, [
        _step(-1, "probe", 14.0, 0.0),  # the point's zero
        _step(-1, "probe", 4.0, 0.02),  # approach: free space
        _step(-1, "probe", 3.2, 4.1),  # contact
        _step(-1, "probe", 3.0, 5.6),
        _step(-1, "probe", 4.0, None),  # backed off to where free space was read
        _step(-1, "probe", 3.67, 1.2),  # in again
        _step(-1, "probe", 14.0, None),
    ])
    passes = passes_before([point], noise_n=0.14)
    assert passes[0] == [0, 0, 0, 0, 0, 1, 1]
