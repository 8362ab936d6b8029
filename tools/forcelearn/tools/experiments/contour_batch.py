"""Paper §4 for many seeds or settings at once: the batched learner on the batched cells.

:func:`run_contour_batch` takes configs that share the task, geometry and trial
budget (they may differ in every learner parameter and the seed) and returns one
summary per config, with the same figures as
:func:`forcelearn.tools.experiments.contour.run_contour` and the same values
except the timing ones (``wall_s`` is the batch's, ``steps_per_s`` the batch's
aggregate rate).
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np

from forcelearn.batch_trainer import BatchResult, train_batch
from forcelearn.emulators.physics.two_link_arm import TwoLinkContourCell
from forcelearn.emulators.physics.two_link_batch import TwoLinkContourCells
from forcelearn.errors import ConfigError
from forcelearn.learning.batched import BatchedSRVLearner
from forcelearn.run_output import final_figures
from forcelearn.tasks.contour import ContourTask
from forcelearn.tasks.contour_batch import BatchedContourTask
from forcelearn.tools.experiments.contour import ContourConfig
from forcelearn.trainer import converged_trial, criterion_trial, run_trial


def run_contour_batch(
    configs: Sequence[ContourConfig], on_member_done: Callable[[int], Any] | None = None
) -> tuple[list[dict[str, Any]], BatchResult]:
    """Run every config as one member of a batch; return the summaries and the raw result.

    Raises:
        ConfigError: the configs differ in task, geometry or trials (run them in
            separate batches).
    """
    if not configs:
        return [], BatchResult([], [], [])
    first = configs[0]
    for c in configs[1:]:
        if (c.task, c.geometry, c.trials) != (first.task, first.geometry, first.trials):
            raise ConfigError(
                "a contour batch needs one task, geometry and trial count; group the "
                "configs by them and run one batch per group"
            )
    size = len(configs)
    task = BatchedContourTask(TwoLinkContourCells(first.geometry, size), first.task)
    learner = BatchedSRVLearner(
        task.grid,
        2,
        [c.learner for c in configs],
        [c.seed for c in configs],
        output=task.output_map(),
    )
    started = time.perf_counter()
    result = train_batch(learner, task, first.trials, on_member_done)
    wall_s = time.perf_counter() - started
    total_steps = sum(result.steps)
    single = ContourTask(TwoLinkContourCell(first.geometry), first.task)
    summaries = []
    for b, config in enumerate(configs):
        records = result.records[b]
        switch = result.switch_trial[b]
        greedy, _ = run_trial(learner.member(b), single, len(records), learn=False)
        converged_at = converged_trial(records, single.steps_per_trial, single.desired_force_n)
        summaries.append(
            {
                "task": "contour",
                "mode": "two-phase" if config.learner.generalized_phase else "specialized-only",
                "seed": config.seed,
                "trials": len(records),
                "phase_switch_trial": switch,
                "criterion_trial": criterion_trial(records, config.learner.success_trials),
                "converged_trial": converged_at,
                "converged": converged_at is not None,
                **final_figures(records),
                "switch_force_rms_n": records[switch].force_rms_n if switch is not None else None,
                "failures": sum(r.failed for r in records),
                "greedy_steps": greedy.steps,
                "greedy_force_rms_n": greedy.force_rms_n,
                "steps": result.steps[b],
                "wall_s": round(wall_s, 3),
                "steps_per_s": round(total_steps / wall_s, 1) if wall_s > 0 else None,
                "batch_size": size,
            }
        )
    result.extra["force_rms"] = [np.array([r.force_rms_n for r in rs]) for rs in result.records]
    return summaries, result
