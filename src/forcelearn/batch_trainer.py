"""The trial loop (S3-S9) for a batched learner on a batched task: every member its own run.

Members step in lockstep, one control step each per batch step; a member whose
trial ends (failure or a complete path) is recorded, advances its own phase
schedule and starts its next trial at the next batch step, independently of
the others; a member that has run its ``trials`` rests until the slowest one is
done. Member ``b``'s :class:`~forcelearn.trainer.TrialRecord` list equals, bit
for bit, what :func:`forcelearn.trainer.train` gives a single learner with the
same seed and parameters (tests/tasks/test_contour_batch.py).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any, Protocol

import numpy as np

from forcelearn.learning.batched import BatchedSRVLearner
from forcelearn.trainer import TrialRecord


class BatchOutcomeLike(Protocol):
    """Arrays over the stepped members: next input, evaluation, failure, force error."""

    @property
    def x(self) -> np.ndarray:
        """Next inputs, (M, ndim)."""
        ...

    @property
    def r(self) -> np.ndarray:
        """Evaluations, (M,)."""
        ...

    @property
    def failed(self) -> np.ndarray:
        """True ends that member's trial, (M,)."""
        ...

    @property
    def force_error_n(self) -> np.ndarray:
        """Measured minus desired force, (M,), N."""
        ...


class BatchedTask(Protocol):
    """An episodic task over ``B`` members (e.g. :class:`BatchedContourTask`)."""

    steps_per_trial: int
    start_force_n: np.ndarray

    def reset(self, members: np.ndarray) -> np.ndarray:
        """Return ``members`` to the start; return their inputs (M, ndim)."""
        ...

    def step(self, members: np.ndarray, command: np.ndarray) -> BatchOutcomeLike:
        """Apply one control output per member; return what followed."""
        ...


@dataclass
class BatchResult:
    """Per member: its trial records, phase-switch trial and controller steps."""

    records: list[list[TrialRecord]]
    switch_trial: list[int | None]
    steps: list[int]
    batch_steps: int = 0
    """Lockstep iterations run (the slowest member's step count)."""
    extra: dict[str, Any] = field(default_factory=dict)


def train_batch(
    learner: BatchedSRVLearner,
    task: BatchedTask,
    trials: int,
    on_member_done: Callable[[int], Any] | None = None,
) -> BatchResult:
    """Run ``trials`` trials for every member of ``learner`` on ``task`` (S3-S9 per member).

    ``on_member_done(b)`` is called when member ``b`` finishes its last trial.
    """
    size = learner.size
    steps_per_trial = task.steps_per_trial
    result = BatchResult([[] for _ in range(size)], [None] * size, [0] * size)
    if trials < 1:
        return result
    r_log = np.zeros((size, steps_per_trial))
    error_log = np.zeros((size, steps_per_trial))
    k = np.zeros(size, dtype=np.int64)
    everyone = np.arange(size)
    x = np.asarray(task.reset(everyone), dtype=float).copy()
    start_force = task.start_force_n.copy()
    active = np.ones(size, dtype=bool)
    members = everyone
    while members.size:
        action = learner.act(members, x[members])
        outcome = task.step(members, action.output)
        learner.learn(action, outcome.r)
        at = k[members]
        r_log[members, at] = outcome.r
        error_log[members, at] = outcome.force_error_n
        k[members] = at + 1
        x[members] = outcome.x
        result.batch_steps += 1
        ended = members[outcome.failed | (at + 1 == steps_per_trial)]
        if not ended.size:
            continue
        failed_now = dict(zip(members.tolist(), outcome.failed.tolist(), strict=True))
        for b in ended.tolist():
            n = int(k[b])
            failed = failed_now[b]
            records = result.records[b]
            errors = error_log[b, :n]
            records.append(
                TrialRecord(
                    index=len(records),
                    phase=learner.phase(b).name.lower(),
                    steps=n - (1 if failed else 0),
                    failed=failed,
                    mean_r=float(np.mean(r_log[b, :n])),
                    force_rms_n=float(np.sqrt(np.mean(np.square(errors)))),
                    start_force_n=float(start_force[b]),
                )
            )
            result.steps[b] += n
            if learner.end_trial(b, success=not failed):
                result.switch_trial[b] = len(records) - 1
            if len(records) == trials:
                active[b] = False
                if on_member_done is not None:
                    on_member_done(b)
        again = ended[active[ended]]
        if again.size:
            x[again] = task.reset(again)
            start_force[again] = task.start_force_n[again]
            k[again] = 0
        members = np.flatnonzero(active)
    return result
