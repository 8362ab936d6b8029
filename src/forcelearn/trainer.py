"""The trial loop of paper §3.1 (S3-S9), task-agnostic, with the project's convergence rule.

A task is episodic: ``reset()`` returns the start input; ``step(command)``
applies one control output and returns the next input, the evaluation r
(smaller is better) and whether the step failed (r > 1, or a safety or range
violation). A failure ends the trial and the task returns to the start.

**Converged** (used everywhere the project reports convergence): the first
trial t such that trials t..t+9 all complete the path without failure and each
has a force RMS error at most 5 % of the desired force.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any, Protocol

import numpy as np

from forcelearn.learning import SRVLearner

CONVERGENCE_WINDOW = 10
"""Consecutive trials that must all be complete and within tolerance."""
CONVERGENCE_TOLERANCE = 0.05
"""Force RMS error allowed per trial, as a fraction of the desired force."""


@dataclass(frozen=True)
class StepOutcome:
    """What a task reports after one control step."""

    x: np.ndarray
    """The next input (state) vector, in the task's input units."""
    r: float
    """Evaluation feedback; smaller is better, > 1 is a failure."""
    failed: bool
    """True ends the trial as a failure."""
    force_n: float
    """Measured normal force after the step, N."""
    force_error_n: float
    """Measured minus desired force, N."""
    extras: dict[str, float] = field(default_factory=dict)
    """Task-specific figures for the step log (velocity error, positions ...)."""


class EpisodicTask(Protocol):
    """A learning task: start input, one step per control output, evaluation and failure."""

    name: str
    steps_per_trial: int
    desired_force_n: float
    start_force_n: float
    """Contact force measured at the start pose of the present trial, N."""

    def reset(self) -> np.ndarray:
        """Return to the start condition; return the start input."""
        ...

    def step(self, command: np.ndarray) -> StepOutcome:
        """Apply one control output; return what followed."""
        ...


@dataclass(frozen=True)
class TrialRecord:
    """One row of trials.csv."""

    index: int
    phase: str
    steps: int
    failed: bool
    mean_r: float
    force_rms_n: float
    start_force_n: float
    cell_time_s: float = math.nan
    """Time the trial held the cell (the robot's clock), s; NaN for pure simulations."""


@dataclass
class TrialLog:
    """Per-step log of one trial (the step-log CSVs and the figures read it)."""

    index: int
    phase: str
    rows: list[dict[str, float]] = field(default_factory=list)


StepHook = Callable[[int, str, dict[str, float]], Any]
"""``on_step(trial_index, phase, row)``: called after every step with its step-log row.

The row is the trainer's own: a hook must copy it before changing anything.
"""


def run_trial(
    learner: SRVLearner,
    task: EpisodicTask,
    index: int,
    learn: bool = True,
    on_step: StepHook | None = None,
) -> tuple[TrialRecord, TrialLog]:
    """Run one trial (S3-S8 per step until the path ends or a step fails); no phase update.

    With ``learn=False`` the learner acts with its mean μ (no search) and learns
    nothing: an evaluation of the learned policy that leaves the learner as it was.
    ``on_step`` (live views) sees each step's log row as soon as it is made.
    """
    phase = learner.phase.name.lower()
    x = task.reset()
    log = TrialLog(index, phase)
    rs: list[float] = []
    errors: list[float] = []
    failed = False
    for k in range(task.steps_per_trial):
        action = learner.act(x, explore=learn)
        outcome = task.step(action.output)
        if learn:
            learner.learn(action, outcome.r)
        rs.append(outcome.r)
        errors.append(outcome.force_error_n)
        row = {
            "step": float(k + 1),
            "r": outcome.r,
            "force_n": outcome.force_n,
            "force_error_n": outcome.force_error_n,
            "sigma": action.sigma,
            **{f"mean_{i}": float(v) for i, v in enumerate(action.mean)},
            **{f"command_{i}": float(v) for i, v in enumerate(action.output)},
            **outcome.extras,
        }
        log.rows.append(row)
        if on_step is not None:
            on_step(index, phase, row)
        x = outcome.x
        if outcome.failed:
            failed = True
            break
    record = TrialRecord(
        index=index,
        phase=phase,
        steps=len(rs) - (1 if failed else 0),
        failed=failed,
        mean_r=float(np.mean(rs)) if rs else math.nan,
        force_rms_n=float(np.sqrt(np.mean(np.square(errors)))) if errors else math.nan,
        start_force_n=float(task.start_force_n),
        cell_time_s=float(getattr(task, "trial_cell_time_s", math.nan)),
    )
    return record, log


def criterion_trial(records: Sequence[TrialRecord], success_trials: int) -> int | None:
    """Return the trial whose success first completed ``success_trials`` successes in a row.

    The global criterion, measured on the records whatever the phase, so runs
    that never had a generalized phase (the specialized-only ablation) can be
    compared with two-phase runs.
    """
    run = 0
    for record in records:
        run = 0 if record.failed else run + 1
        if run == success_trials:
            return record.index
    return None


def converged_trial(
    records: Sequence[TrialRecord],
    steps_per_trial: int,
    desired_force_n: float,
    window: int = CONVERGENCE_WINDOW,
    tolerance: float = CONVERGENCE_TOLERANCE,
) -> int | None:
    """Return the first trial index t where trials t..t+window−1 are complete and in band."""
    limit = tolerance * abs(desired_force_n)
    good = [
        (not r.failed) and r.steps == steps_per_trial and r.force_rms_n <= limit for r in records
    ]
    run = 0
    for i, ok in enumerate(good):
        run = run + 1 if ok else 0
        if run == window:
            return records[i - window + 1].index
    return None


@dataclass
class TrainingResult:
    """Everything a run produced: per-trial records and the logs worth keeping."""

    records: list[TrialRecord] = field(default_factory=list)
    switch_trial: int | None = None
    switch_log: TrialLog | None = None
    first_log: TrialLog | None = None
    last_log: TrialLog | None = None
    logs: dict[int, TrialLog] = field(default_factory=dict)
    steps: int = 0


def train(
    learner: SRVLearner,
    task: EpisodicTask,
    trials: int,
    keep_logs: Sequence[int] = (),
    on_trial: Callable[[TrialRecord, TrialLog, SRVLearner], Any] | None = None,
    result: TrainingResult | None = None,
    on_step: StepHook | None = None,
) -> TrainingResult:
    """Run ``trials`` trials (S3-S9) and update the phase schedule after each (global criterion).

    Args:
        learner: the SRV learner (its phase schedule is advanced here).
        task: the episodic task.
        trials: how many trials to run.
        keep_logs: trial indices whose step logs are kept besides first, switch and last.
        on_trial: called after each trial with its record, step log and the learner
            (progress bars, checkpoints); the phase schedule is already updated.
        result: a result to continue (resumed runs); a new one by default.
        on_step: called after each step with the trial index, phase and step-log row.
    """
    result = result or TrainingResult()
    start = len(result.records)
    for index in range(start, start + trials):
        record, log = run_trial(learner, task, index, on_step=on_step)
        switched = learner.end_trial(success=not record.failed)
        result.records.append(record)
        result.steps += len(log.rows)
        if index == 0:
            result.first_log = log
        if switched:
            result.switch_trial = index
            result.switch_log = log
        if index in keep_logs:
            result.logs[index] = log
        result.last_log = log
        if on_trial is not None:
            on_trial(record, log, learner)
    return result
