"""The comparison of issue 15: the paper's learner against classic and modern baselines on §5.

One run = one method on one cell variant for one seed, through ``forcelearn/Surface-v0``
on the emulated cell (real drivers), scored by ``converged_trial`` and stopped by
the budget rule of :mod:`forcelearn.baselines.runner` (converged + 10 trials, or
``trials``). Runs go through the study runner, so ``forcelearn study baselines
--set method=srv,pi,ilc,cma --set variant=default,fast_wear,soft`` works like any
study; this module's ``main`` runs the same study and writes
``docs/results/baselines.md`` and its figure::

    python -m forcelearn.tools.baselines_study [--seeds 10] [--methods srv,pi,ilc,cma]
        [--variants default,fast_wear,soft] [--trials 300] [--workers 2]

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

import argparse
import logging
import math
import statistics
import sys
import time
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np

from forcelearn.baselines.controllers import (
    ForceController,
    ForceControlParams,
    ILCController,
    ILCParams,
    PathSearchController,
    PathSearchParams,
    SRVController,
)
from forcelearn.baselines.runner import AFTER_CONVERGED, TrialRecorder, run_controller
from forcelearn.baselines.sac import SACParams, run_sac
from forcelearn.errors import ConfigError, LinkError, SensorError
from forcelearn.tools.cell_config import CellConfig, load_cell_config
from forcelearn.tools.study_grid import RunSpec, apply_overrides
from forcelearn.trainer import CONVERGENCE_WINDOW, converged_trial, criterion_trial

log = logging.getLogger(__name__)

METHODS = ("srv", "pi", "ilc", "cma", "sac")
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
    pi: ForceControlParams = field(default_factory=ForceControlParams)
    ilc: ILCParams = field(default_factory=ILCParams)
    cma: PathSearchParams = field(default_factory=PathSearchParams)
    sac: SACParams = field(default_factory=SACParams)

    def __post_init__(self) -> None:
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


def run_baseline(config: BaselinesConfig, seed: int) -> tuple[dict[str, Any], dict[str, list]]:
    """Run one method on one variant for one seed; return the summary and per-trial curves."""
    from forcelearn.envs import SurfaceEnv

    cell = variant_config(config.variant)
    env = SurfaceEnv(cell, seed=seed)
    started = time.perf_counter()
    try:
        if config.method == "sac":
            recorder: TrialRecorder = run_sac(env, seed, config.trials, config.sac)[0]
        else:
            controller = {
                "srv": lambda: SRVController(env, cell.learner, seed),
                "pi": lambda: ForceController(env, config.pi),
                "ilc": lambda: ILCController(env, config.ilc),
                "cma": lambda: PathSearchController(env, seed, config.cma),
            }[config.method]()
            recorder = run_controller(env, controller, config.trials, seed)
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


def curves_of(recorder: TrialRecorder) -> dict[str, list]:
    """Per-trial arrays saved beside the run (learning-curve figure)."""
    records = recorder.records
    return {
        "force_rms_n": [r.force_rms_n for r in records],
        "cell_time_s": [r.cell_time_s for r in records],
        "steps": [r.steps for r in records],
        "failed": [int(r.failed) for r in records],
        "peak_force_n": list(recorder.stats.peak_force_n),
    }


def base_config() -> BaselinesConfig:
    """The study's base config (its dotted keys are the --set keys)."""
    return BaselinesConfig()


def run_chunk(specs: list[RunSpec]) -> list[dict[str, Any]]:
    """Run specs one after the other (each opens its own emulated cell); one row each."""
    from forcelearn.tools.study_tasks import CURVES, result_row

    rows = []
    for spec in specs:
        config = apply_overrides(BaselinesConfig(trials=spec.trials), dict(spec.overrides))
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


# -- the report -----------------------------------------------------------------------------


def _median_range(values: list[float], fmt: str) -> str:
    finite = [v for v in values if v is not None and math.isfinite(v)]
    if not finite:
        return "–"
    return (
        f"{fmt.format(statistics.median(finite))} "
        f"({fmt.format(min(finite))}–{fmt.format(max(finite))})"
    )


def report_rows(rows: list[dict[str, Any]], trials: int) -> list[str]:
    """The Markdown table: one line per variant × method."""
    lines = [
        "| variant | method | converged | trials to converge | cell time to converge (min) "
        "| final force RMS (N) | worst force (N) | failed trials |",
        "|---|---|---|---|---|---|---|---|",
    ]
    groups: dict[tuple[str, str], list[dict[str, Any]]] = {}
    for row in rows:
        groups.setdefault((row["variant"], row["method"]), []).append(row)
    for variant in VARIANTS:
        for method in METHODS:
            runs = groups.get((variant, method))
            if not runs:
                continue
            conv = [r["converged_trial"] for r in runs]
            reached = [c for c in conv if c is not None]
            times = [r["cell_time_to_converge_s"] for r in runs]
            lines.append(
                f"| {variant} | {method} | {len(reached)} / {len(runs)} | "
                f"{_median_range([trials if c is None else c for c in conv], '{:.0f}')} | "
                f"{_median_range([t / 60 for t in times if t is not None], '{:.1f}')} | "
                f"{_median_range([r['final_force_rms_n'] for r in runs], '{:.2f}')} | "
                f"{_median_range([r['worst_force_n'] for r in runs], '{:.1f}')} | "
                f"{_median_range([r['failures'] for r in runs], '{:.0f}')} |"
            )
    return lines


def learning_curves_figure(
    rows: list[dict[str, Any]], curves: dict[str, dict[str, np.ndarray]], trials: int, path: Path
) -> None:
    """Force RMS per trial, median and range over seeds, one line per method, one panel a variant.

    A run stopped by the budget rule is held at its final force RMS after its last trial.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    variants = [v for v in VARIANTS if any(r["variant"] == v for r in rows)]
    fig, axes = plt.subplots(1, len(variants), figsize=(5 * len(variants), 4), sharey=True)
    axes = np.atleast_1d(axes)
    for ax, variant in zip(axes, variants, strict=True):
        for method in METHODS:
            runs = [r for r in rows if r["variant"] == variant and r["method"] == method]
            if not runs:
                continue
            table = np.full((len(runs), trials), np.nan)
            for i, run in enumerate(runs):
                rms = np.asarray(curves[run["run_id"]]["force_rms_n"], dtype=float)
                table[i, : len(rms)] = rms
                table[i, len(rms) :] = run["final_force_rms_n"]
            x = np.arange(trials)
            (line,) = ax.plot(x, np.nanmedian(table, axis=0), lw=1.2, label=method)
            ax.fill_between(
                x,
                np.nanmin(table, axis=0),
                np.nanmax(table, axis=0),
                alpha=0.15,
                color=line.get_color(),
            )
        ax.axhline(0.05 * 19.61, color="k", ls=":", lw=1, label="5 % band")
        ax.set_yscale("log")
        ax.set_title(f"cell: {variant}")
        ax.set_xlabel("trial")
    axes[0].set_ylabel("force RMS per trial (N)")
    axes[-1].legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def saved_rows(study_dir: Path, trials: int) -> list[dict[str, Any]]:
    """Every finished run of ``trials`` trials saved in a study folder (any method, seed)."""
    import json

    rows = [json.loads(p.read_text()) for p in sorted((study_dir / "runs").glob("*.json"))]
    return sorted(
        (r for r in rows if r["trials"] == trials and r["task"] == "baselines"),
        key=lambda r: (r["variant"], r["method"], r["seed"]),
    )


def main(argv: list[str] | None = None) -> int:
    """Run the comparison study and write docs/results/baselines.md with its figure."""
    from forcelearn.tools.study_runner import load_curves, run_study
    from forcelearn.tools.study_tasks import get_task

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=10)
    parser.add_argument("--trials", type=int, default=300)
    parser.add_argument("--methods", default="srv,pi,ilc,cma")
    parser.add_argument("--variants", default=",".join(VARIANTS))
    parser.add_argument("--workers", type=int, help="local processes (default: all cores)")
    parser.add_argument("--out", type=Path, default=Path("docs/results"))
    parser.add_argument("--study-dir", type=Path, default=Path("runs/study-baselines"))
    parser.add_argument(
        "--report-only",
        action="store_true",
        help="run nothing: tabulate every run already saved in --study-dir",
    )
    args = parser.parse_args(argv)
    methods, variants = args.methods.split(","), args.variants.split(",")
    points = [{"method": m, "variant": v} for v in variants for m in methods]
    command = (
        f"python -m forcelearn.tools.baselines_study --seeds {args.seeds} --trials {args.trials} "
        f"--methods {args.methods} --variants {args.variants}"
    )
    started = time.perf_counter()
    if args.report_only:
        rows = saved_rows(args.study_dir, args.trials)
        header = f"Tabulated from the runs saved in `{args.study_dir}` by `{command}`"
    else:
        outcome = run_study(
            get_task("baselines"),
            args.study_dir,
            args.trials,
            range(args.seeds),
            points,
            workers=args.workers,
            command=command,
        )
        rows = outcome.rows
        header = (
            f"Made by `{command}` ({time.perf_counter() - started:.0f} s wall, "
            f"{outcome.ran} runs run now, {outcome.reused} reused)"
        )
    curves = {r["run_id"]: load_curves(args.study_dir, r["run_id"]) for r in rows}
    args.out.mkdir(parents=True, exist_ok=True)
    figure = args.out / "baselines_learning_curves.png"
    learning_curves_figure(rows, curves, args.trials, figure)
    table = report_rows(rows, args.trials)
    (args.out / "baselines_table.md").write_text(header + ".\n\n" + "\n".join(table) + "\n")
    print("\n".join(table))
    print(f"wrote {figure} and {args.out / 'baselines_table.md'}")
    print(f"budget rule: stop at converged + {CONVERGENCE_WINDOW} + {AFTER_CONVERGED} trials")
    return 0


if __name__ == "__main__":
    sys.exit(main())
