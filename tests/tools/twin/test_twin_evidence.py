"""The identification's bursts count in a member's score (its BIC)."""

from __future__ import annotations

import numpy as np

from forcelearn.records import BurstRecord, MoveRecord, StepRecord, TrialRecords
from forcelearn.tools.twin.arrays import to_arrays
from forcelearn.tools.twin.fit import evidence_bic
from forcelearn.tools.twin.identify import IDENTIFY_TRIAL


def _trial(trial: int, forces: list[float]) -> TrialRecords:
    steps = []
    for k, force in enumerate(forces):
        move = MoveRecord((0.0, -float(k), 0.0), (0.0, -float(k), 0.0), k, k + 0.1, k + 0.2)
        burst = BurstRecord(force, 0.1, force, force, 16, k + 0.2, 0.01, force)
        steps.append(StepRecord(trial, k, "step", move, burst))
    return TrialRecords(trial, steps)


def test_a_member_that_misses_the_holds_scores_worse() -> None:
    """Off by 0.5 N on the identification's bursts: a higher BIC than one that fits them."""
    held = [5.0, 4.6, 4.4, 4.3, 4.25, 4.2]  # a hold relaxing
    data = to_arrays([_trial(IDENTIFY_TRIAL, held), _trial(0, [0.0, 3.0, 5.0])])
    fits = np.where(data.has_burst, data.mean_n, np.nan)
    misses = np.where(data.trial[:, None] == IDENTIFY_TRIAL, np.nanmean(held), fits)
    good, count = evidence_bic(data, fits, 0.1, 3)
    bad, _ = evidence_bic(data, misses, 0.1, 3)
    assert count == len(held)
    assert bad > good + 10  # very strong evidence against the member that misses them


def test_without_an_identification_nothing_is_added() -> None:
    """A run's records alone: the score is the held-out trials' only."""
    data = to_arrays([_trial(0, [0.0, 3.0, 5.0]), _trial(1, [0.0, 3.1])])
    assert evidence_bic(data, data.mean_n, 0.1, 3) == (0.0, 1)
