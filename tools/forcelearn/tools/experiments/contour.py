"""Paper §4 end to end: build the two-link cell, the contour task and the learner; run; report.

Used by ``forcelearn sim contour``, by ``tools/contour_study.py`` and by the tests.
A TOML config may hold the tables ``[learner]`` (SRVParams), ``[task]``
(ContourTaskSpec), ``[geometry]`` (ContourGeometry) and ``[run]`` (trials, seed).
"""

from __future__ import annotations

import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

from forcelearn.config import build, check_sections, read_run_table, read_toml
from forcelearn.emulators.physics.two_link_arm import ContourGeometry, TwoLinkContourCell
from forcelearn.errors import ConfigError
from forcelearn.learning import SRVLearner, SRVParams
from forcelearn.run_output import final_figures
from forcelearn.tasks.contour import ContourTask, ContourTaskSpec
from forcelearn.trainer import (
    StepHook,
    TrainingResult,
    TrialLog,
    TrialRecord,
    converged_trial,
    criterion_trial,
    run_trial,
    train,
)

DEFAULT_TRIALS = 4000


@dataclass(frozen=True)
class ContourConfig:
    """Everything a contour run needs; the defaults are the paper's §4 values."""

    learner: SRVParams = field(default_factory=SRVParams)
    task: ContourTaskSpec = field(default_factory=ContourTaskSpec)
    geometry: ContourGeometry = field(default_factory=ContourGeometry)
    trials: int = DEFAULT_TRIALS
    seed: int = 0


def load_config(
    path: str | Path | None, overrides: Mapping[str, Any] | None = None
) -> ContourConfig:
    """Read a contour config file (or the defaults) and apply command-line overrides."""
    data = read_toml(path) if path else {}
    check_sections(data, {"learner", "task", "geometry", "run"})
    trials, seed = read_run_table(data, DEFAULT_TRIALS)
    config = ContourConfig(
        learner=build(SRVParams, data.get("learner"), "learner"),
        task=build(ContourTaskSpec, data.get("task"), "task"),
        geometry=build(ContourGeometry, data.get("geometry"), "geometry"),
        trials=trials,
        seed=seed,
    )
    config.task.check_start(config.geometry.start_theta_deg)
    config = replace(config, **{k: v for k, v in (overrides or {}).items() if v is not None})
    if config.trials < 1:
        raise ConfigError(f"run.trials = {config.trials}: must be >= 1")
    return config


@dataclass
class ContourRun:
    """A finished contour run: its config, the learner, the training result and the summary."""

    config: ContourConfig
    learner: SRVLearner
    task: ContourTask
    result: TrainingResult
    summary: dict[str, Any]


def run_contour(
    config: ContourConfig,
    on_trial: Callable[[TrialRecord, TrialLog, SRVLearner], Any] | None = None,
    on_step: StepHook | None = None,
) -> ContourRun:
    """Run the §4 experiment as configured and return everything it produced."""
    task = ContourTask(TwoLinkContourCell(config.geometry), config.task)
    learner = SRVLearner(task.grid, 2, config.learner, rng=config.seed, output=task.output_map())
    started = time.perf_counter()
    result = train(learner, task, config.trials, on_trial=on_trial, on_step=on_step)
    wall_s = time.perf_counter() - started
    greedy, _ = run_trial(learner, task, len(result.records), learn=False)
    converged_at = converged_trial(result.records, task.steps_per_trial, task.desired_force_n)
    summary: dict[str, Any] = {
        "task": "contour",
        "mode": "two-phase" if config.learner.generalized_phase else "specialized-only",
        "seed": config.seed,
        "trials": len(result.records),
        "phase_switch_trial": result.switch_trial,
        "criterion_trial": criterion_trial(result.records, config.learner.success_trials),
        "converged_trial": converged_at,
        "converged": converged_at is not None,
        **final_figures(result.records),
        "switch_force_rms_n": (
            result.records[result.switch_trial].force_rms_n
            if result.switch_trial is not None
            else None
        ),
        "failures": sum(r.failed for r in result.records),
        "greedy_steps": greedy.steps,
        "greedy_force_rms_n": greedy.force_rms_n,
        "steps": result.steps,
        "wall_s": round(wall_s, 3),
        "steps_per_s": round(result.steps / wall_s, 1) if wall_s > 0 else None,
    }
    return ContourRun(config, learner, task, result, summary)
