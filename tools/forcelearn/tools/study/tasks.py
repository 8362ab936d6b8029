"""The tasks ``forcelearn study`` can run, each an adapter from run specs to result rows.

A task adapter names its base config (whose dotted keys ``--set`` may change),
says which runs may share a batch, and runs a chunk of specs, returning one
flat row per run. Chunks run in worker processes (local or on a Dask cluster),
so the runners are module-level functions of picklable arguments and return
their rows instead of writing files: the study's own process writes them.

=========  ===================================================================
task       what a run is
=========  ===================================================================
contour    paper §4, the batched simulation (many runs per chunk, one core)
surface    paper §5, one ``forcelearn run`` on the emulated cell per run
baselines  §5 through ``forcelearn/Surface-v0``: one method (srv, pi, ilc, cma,
           sac) on one cell variant per run (:mod:`.baselines_study`)
=========  ===================================================================
"""

from __future__ import annotations

import tempfile
from collections.abc import Callable, Hashable
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

from forcelearn.errors import ConfigError
from forcelearn.tools.study.grid import CURVES, RunSpec, apply_overrides, result_row


@dataclass(frozen=True)
class StudyTask:
    """How ``forcelearn study`` runs one task."""

    name: str
    description: str
    base_config: Callable[[], Any]
    run_chunk: Callable[[list[RunSpec]], list[dict[str, Any]]]
    group_key: Callable[[RunSpec], Hashable]
    """Runs with equal keys may share a chunk (a batch)."""
    batched: bool
    """True: a chunk of many runs costs little more than one (run them together)."""
    cost: Callable[[RunSpec], float] | None = None
    """A run's expected cost, relative (the runner starts the costliest chunks first, so the
    last to finish are short ones); None: in grid order."""


def _contour_config(spec: RunSpec) -> Any:
    from forcelearn.tools.experiments.contour import ContourConfig

    config = ContourConfig(trials=spec.trials, seed=spec.seed)
    return apply_overrides(config, dict(spec.overrides))


def _contour_base() -> Any:
    from forcelearn.tools.experiments.contour import ContourConfig

    return ContourConfig()


def run_contour_chunk(specs: list[RunSpec]) -> list[dict[str, Any]]:
    """Run §4 specs as one batch (they share task, geometry and trials); one row per spec."""
    from forcelearn.tools.experiments.contour_batch import run_contour_batch

    configs = [_contour_config(s) for s in specs]
    summaries, result = run_contour_batch(configs)
    rows = [result_row(s, c, m) for s, c, m in zip(specs, configs, summaries, strict=True)]
    for row, records in zip(rows, result.records, strict=True):
        row[CURVES] = {
            "steps": [r.steps for r in records],
            "force_rms_n": [r.force_rms_n for r in records],
        }
    return rows


def _contour_group(spec: RunSpec) -> Hashable:
    return tuple((k, v) for k, v in spec.overrides if not k.startswith("learner."))


def _surface_base() -> Any:
    from forcelearn.site.config import load_cell_config

    return load_cell_config(None)


def run_surface_chunk(specs: list[RunSpec]) -> list[dict[str, Any]]:
    """Run §5 specs one after the other, each a whole emulated-cell run in a scratch folder."""
    from forcelearn.tools.experiments.surface_run import execute
    from forcelearn.tools.experiments.surface_state import prepare_run

    rows = []
    for spec in specs:
        with tempfile.TemporaryDirectory(prefix="forcelearn-study-") as folder:
            run, _ = prepare_run(None, Path(folder) / "run", spec.trials, spec.seed, resume=False)
            run.config = apply_overrides(run.config, dict(spec.overrides))
            run = replace(run)  # a fresh copy: nothing of the base run is shared
            summary = execute(run, None)
        rows.append(result_row(spec, run.config, summary))
    return rows


def _baselines_base() -> Any:
    from forcelearn.tools.study.baselines import base_config

    return base_config()


def run_baselines_chunk(specs: list[RunSpec]) -> list[dict[str, Any]]:
    """Run comparison specs (method × cell variant × seed) one after the other."""
    from forcelearn.tools.study.baselines import run_chunk

    return run_chunk(specs)


def _baselines_group(spec: RunSpec) -> Hashable:
    from forcelearn.tools.study.baselines import probe_group

    return probe_group(spec)


def _baselines_cost(spec: RunSpec) -> float:
    from forcelearn.tools.study.baselines import run_cost

    return run_cost(spec)


TASKS: dict[str, StudyTask] = {
    "contour": StudyTask(
        "contour",
        "paper §4 two-link contour simulation (batched learner)",
        _contour_base,
        run_contour_chunk,
        _contour_group,
        batched=True,
    ),
    "surface": StudyTask(
        "surface",
        "paper §5 sponge task on the emulated cell (one forcelearn run per run)",
        _surface_base,
        run_surface_chunk,
        lambda spec: spec.run_id,
        batched=False,
    ),
    "baselines": StudyTask(
        "baselines",
        "paper §5 through the Gymnasium env: SRV vs force control, ILC, CMA-ES, SAC",
        _baselines_base,
        run_baselines_chunk,
        _baselines_group,
        batched=True,
        cost=_baselines_cost,
    ),
}


def get_task(name: str) -> StudyTask:
    """Return the adapter of task ``name``; an unknown name lists the known ones."""
    try:
        return TASKS[name]
    except KeyError:
        raise ConfigError(f"unknown study task {name!r}; known: {', '.join(TASKS)}") from None
