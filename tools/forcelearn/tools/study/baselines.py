"""The paper's learner against classic and modern baselines on §5 (docs/results/baselines.md).

One run = one method on one cell variant for one seed, through ``forcelearn/Surface-v0``
on the emulated cell (real drivers; ``env = "wire"``) or through one numpy cell of
``forcelearn/SurfaceVec-v0`` started from the same wire-level cell's probe (``env =
"vec"``: the methods that need hundreds of trials, CMA-ES and SAC), scored by
``converged_trial`` and stopped by the budget rule of :mod:`forcelearn.baselines.runner`
(converged + 10 trials, or ``trials``). Runs go through the study runner, so
``forcelearn study baselines --set method=srv,pi,ilc,cma --set variant=default,fast_wear,soft``
works like any study; :mod:`.baselines_report` runs the same study and writes
``docs/results/baselines.md`` and its figure.

=============  ==================================================================
variant        the emulated cell
=============  ==================================================================
``default``    the default cell (docs/surface.md)
``fast_wear``  the sponge wears five times faster (softening over 30 passes instead
               of 150, set over 20 instead of 100)
``soft``       a softer sponge: 1.4 N/mm instead of 2.0 N/mm (30 % softer)
=============  ==================================================================
"""

from __future__ import annotations

import logging
import math
import statistics
import time
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from typing import Any

import gymnasium

from forcelearn.baselines.controllers import (
    ForceController,
    ForceControlParams,
    ILCController,
    ILCParams,
    PathSearchController,
    PathSearchParams,
    SRVController,
)
from forcelearn.baselines.runner import Controller, TrialRecorder, run_controller
from forcelearn.baselines.sac import SACParams, run_sac
from forcelearn.errors import ConfigError, LinkError, SensorError
from forcelearn.site.config import CellConfig, load_cell_config
from forcelearn.tasks.surface_warm_start import check_learner_start
from forcelearn.tools.study.grid import CURVES, RunSpec, apply_overrides, result_row
from forcelearn.trainer import converged_trial, criterion_trial

log = logging.getLogger(__name__)

METHODS = ("srv", "pi", "ilc", "cma", "sac")
ENVS = ("wire", "vec")
VARIANTS = ("default", "fast_wear", "soft")
DEVICE_RETRIES = 2
"""A run whose emulated devices time out (host overloaded: the drivers' watchdogs are
wall-clock) is started again from scratch on a fresh cell, at most this many times."""
FINAL_TRIALS = 10
"""Trials whose median force RMS is the 'final force RMS' (the last ones of the run)."""


@dataclass(frozen=True)
class BaselinesConfig:
    """One run of the comparison; ``forcelearn study baselines --set KEY=...`` sweeps these."""

    method: str = "srv"
    """srv, pi, ilc, cma or sac."""
    variant: str = "default"
    """default, fast_wear or soft (module docstring)."""
    trials: int = 300
    learner_start: str = "cold"
    """The cell's ``[run] learner_start``: "cold" (the study as first documented: the env's
    probe of 3 points, srv at μ = 0) or "probe" (the probe adds its refine points, every
    method gets that path, srv starts on it)."""
    pi: ForceControlParams = field(default_factory=ForceControlParams)
    ilc: ILCParams = field(default_factory=ILCParams)
    cma: PathSearchParams = field(default_factory=PathSearchParams)
    sac: SACParams = field(default_factory=SACParams)
    env: str = "wire"
    """"wire": ``Surface-v0`` through the real drivers; "vec": one numpy cell of
    ``SurfaceVec-v0`` from the wire-level cell's probe (docs/results/surface-vec.md)."""

    def __post_init__(self) -> None:
        check_learner_start(self.learner_start)
        if self.env not in ENVS:
            raise ConfigError(f"env = {self.env!r}: one of {', '.join(ENVS)}")
        if self.method not in METHODS:
            raise ConfigError(f"method = {self.method!r}: one of {', '.join(METHODS)}")
        if self.variant not in VARIANTS:
            raise ConfigError(f"variant = {self.variant!r}: one of {', '.join(VARIANTS)}")


def variant_config(variant: str, base: CellConfig | None = None) -> CellConfig:
    """The emulated cell of a variant."""
    config = base or load_cell_config(None)
    sponge = config.emulator.sponge
    if variant == "fast_wear":
        sponge = replace(sponge, softening_passes=30.0, set_passes=20.0)
    elif variant == "soft":
        sponge = replace(sponge, stiffness_n_per_mm=1.4)
    elif variant != "default":
        raise ConfigError(f"variant = {variant!r}: one of {', '.join(VARIANTS)}")
    return replace(config, emulator=replace(config.emulator, sponge=sponge))


_PROBES: dict[tuple[str, str, int], Any] = {}
"""The wire-level probes this process ran for numpy-cell runs: (variant, start, seed) ->
``Probed``. CMA-ES and SAC on a variant and seed start from the same probe, run once."""


def probed(config: BaselinesConfig, seed: int) -> Any:
    """The wire-level cell's probe of ``config``'s variant and start for ``seed`` (cached)."""
    from forcelearn.envs.surface_vec import probe_map

    key = (config.variant, config.learner_start, seed)
    if key not in _PROBES:
        cell = replace(variant_config(config.variant), learner_start=config.learner_start)
        _PROBES[key] = probe_map(cell, seed)
    return _PROBES[key]


def run_baseline(
    config: BaselinesConfig,
    seed: int,
    wrap: Callable[[gymnasium.Env[Any, Any]], gymnasium.Env[Any, Any]] | None = None,
) -> tuple[dict[str, Any], dict[str, list[float]]]:
    """Run one method on one variant for one seed; return the summary and per-trial curves.

    ``wrap``, if given, wraps the environment the method's trials run through
    (under the recorder), e.g. to time them; the controllers still read the
    bare environment's task figures.
    """
    cell = replace(variant_config(config.variant), learner_start=config.learner_start)
    env: Any
    if config.env == "vec":
        from forcelearn.envs.surface_vec import SurfaceSimEnv

        env = SurfaceSimEnv(cell, seed=seed, probed=probed(config, seed))
    else:
        from forcelearn.envs import SurfaceEnv

        env = SurfaceEnv(cell, seed=seed)
    trial_env = wrap(env) if wrap is not None else env
    started = time.perf_counter()
    try:
        if config.method == "sac":
            recorder: TrialRecorder = run_sac(trial_env, seed, config.trials, config.sac)[0]
        else:
            factories: dict[str, Callable[[], Controller]] = {
                "srv": lambda: SRVController(env, cell.learner, seed, config.learner_start),
                "pi": lambda: ForceController(env, config.pi),
                "ilc": lambda: ILCController(env, config.ilc),
                "cma": lambda: PathSearchController(env, seed, config.cma),
            }
            controller = factories[config.method]()
            recorder = run_controller(trial_env, controller, config.trials, seed)
    finally:
        env.close()
    wall_s = time.perf_counter() - started
    return summarize_run(recorder, cell, seed, wall_s), curves_of(recorder)


def summarize_run(
    recorder: TrialRecorder, cell: CellConfig, seed: int, wall_s: float
) -> dict[str, Any]:
    """The figures of the comparison for one run."""
    records = recorder.records
    spec = cell.task
    converged = converged_trial(records, spec.steps_per_trial, spec.desired_force_n)
    cell_times = [r.cell_time_s for r in records]
    tail = [r.force_rms_n for r in records[-FINAL_TRIALS:]]
    return {
        "seed": seed,
        "trials_run": len(records),
        "converged_trial": converged,
        "criterion_trial": criterion_trial(records, cell.learner.success_trials),
        "cell_time_to_converge_s": (
            round(float(sum(cell_times[:converged])), 3) if converged is not None else None
        ),
        "cell_time_s": round(float(sum(cell_times)), 3),
        "final_force_rms_n": statistics.median(tail) if tail else math.nan,
        "worst_force_n": max(recorder.stats.peak_force_n, default=math.nan),
        "failures": sum(r.failed for r in records),
        "steps": sum(r.steps + (1 if r.failed else 0) for r in records),
        "wall_s": round(wall_s, 3),
    }


def curves_of(recorder: TrialRecorder) -> dict[str, list[float]]:
    """Per-trial arrays saved beside the run (learning-curve figure)."""
    records = recorder.records
    return {
        "force_rms_n": [r.force_rms_n for r in records],
        "cell_time_s": [r.cell_time_s for r in records],
        "steps": [r.steps for r in records],
        "failed": [int(r.failed) for r in records],
        "peak_force_n": list(recorder.stats.peak_force_n),
    }


RUN_COST = {"srv-cold": 1.0, "srv": 0.65, "sac": 0.55, "ilc": 0.45, "pi": 0.35, "cma": 0.1}
"""Relative cost of a run by method (srv by start), from the shares of the study's wall time
in docs/results/baselines.md: the runner starts the costliest first."""


def _config_of(spec: RunSpec) -> BaselinesConfig:
    config: BaselinesConfig = apply_overrides(
        BaselinesConfig(trials=spec.trials), dict(spec.overrides)
    )
    return config


def run_cost(spec: RunSpec) -> float:
    """A run's expected cost, relative (:data:`RUN_COST`)."""
    config = _config_of(spec)
    cold = config.method == "srv" and config.learner_start == "cold"
    return RUN_COST["srv-cold" if cold else config.method]


def probe_group(spec: RunSpec) -> tuple[str, ...]:
    """A run's chunk key: one probe's numpy-cell runs share a chunk, every other run alone.

    The numpy-cell runs of one (variant, start, seed) start from one wire-level probe,
    which a process runs once (:func:`probed`).
    """
    config = _config_of(spec)
    if config.env != "vec":
        return (spec.run_id,)
    return ("vec", config.variant, config.learner_start, str(spec.seed))


def base_config() -> BaselinesConfig:
    """The study's base config (its dotted keys are the --set keys)."""
    return BaselinesConfig()


def run_chunk(specs: list[RunSpec]) -> list[dict[str, Any]]:
    """Run specs one after the other (each opens its own emulated cell); one row each."""
    rows = []
    for spec in specs:
        config = _config_of(spec)
        for attempt in range(1 + DEVICE_RETRIES):
            try:
                summary, curves = run_baseline(config, spec.seed)
                break
            except (SensorError, LinkError) as exc:
                if attempt == DEVICE_RETRIES:
                    raise
                log.warning("run %s: %s; starting it again on a fresh cell", spec.run_id, exc)
        summary["device_retries"] = attempt
        row = result_row(spec, config, summary)
        row[CURVES] = curves
        rows.append(row)
    return rows
