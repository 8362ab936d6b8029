"""The report of the baselines comparison: ``docs/results/baselines.md`` and its figure.

Runs the study of :mod:`forcelearn.tools.study.baselines` through the study
runner (finished runs are skipped) and writes the table and the learning-curves
figure::

    python -m forcelearn.tools.results.baselines_report [--seeds 10]
        [--methods srv,pi,ilc,cma,sac] [--vec-methods cma,sac] [--srv-starts probe,cold]
        [--variants default,fast_wear,soft] [--trials 300] [--sac-wire-seeds 3] [--workers 2]

Prints a progress bar per study (runs done, the time left), then the table and the
study's wall and CPU time (this process and its worker processes) with the workers used.
Every method runs with ``learner_start = "probe"`` (the probe's path is each
method's prior); srv also from μ = 0 (``--srv-starts``). The ``--vec-methods``
run on a numpy cell of ``SurfaceVec-v0`` from the same wire-level probe, the
others on ``Surface-v0``; SAC also runs on ``Surface-v0`` for
``--sac-wire-seeds`` seeds of the default variant.
"""

from __future__ import annotations

import argparse
import math
import os
import statistics
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

from forcelearn.baselines.runner import AFTER_CONVERGED
from forcelearn.tools.study.baselines import METHODS, VARIANTS
from forcelearn.trainer import CONVERGENCE_WINDOW


def _median_range(values: list[float], fmt: str) -> str:
    finite = [v for v in values if v is not None and math.isfinite(v)]
    if not finite:
        return "–"
    return (
        f"{fmt.format(statistics.median(finite))} "
        f"({fmt.format(min(finite))}–{fmt.format(max(finite))})"
    )


def label(row: dict[str, Any]) -> str:
    """A table row's method label: the method, srv's start, and the env when numpy."""
    name = str(row["method"])
    if name == "srv":
        name += ", warm start" if row.get("learner_start") == "probe" else ", cold start"
    if row.get("env", "wire") == "vec":
        name += " (numpy cell)"
    elif name.startswith(("cma", "sac")):
        name += " (wire cell)"
    return name


def labels() -> list[str]:
    """Every label, in the table's order."""
    names = ["srv, warm start", "srv, cold start", "pi", "ilc"]
    for method in METHODS[3:]:
        names += [f"{method} (numpy cell)", f"{method} (wire cell)"]
    return names


def report_rows(rows: list[dict[str, Any]], trials: int) -> list[str]:
    """The Markdown table: one line per variant × method (and env, srv's start)."""
    lines = [
        "| variant | method | converged | trials to converge | cell time to converge (min) "
        "| final force RMS (N) | worst force (N) | failed trials | env steps |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    groups: dict[tuple[str, str], list[dict[str, Any]]] = {}
    for row in rows:
        groups.setdefault((row["variant"], label(row)), []).append(row)
    for variant in VARIANTS:
        for method in labels():
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
                f"{_median_range([r['failures'] for r in runs], '{:.0f}')} | "
                f"{_median_range([r['steps'] for r in runs], '{:.0f}')} |"
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
        for method in labels():
            runs = [r for r in rows if r["variant"] == variant and label(r) == method]
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
    named: dict[str, Any] = {}  # every panel's lines (a row may be on one variant only)
    for ax in axes:
        for handle, name in zip(*ax.get_legend_handles_labels(), strict=True):
            named.setdefault(name, handle)
    axes[-1].legend(list(named.values()), list(named), fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def saved_rows(study_dir: Path, trials: int) -> list[dict[str, Any]]:
    """Every finished run of ``trials`` trials saved in a study folder (any method, seed)."""
    import json

    found = sorted(study_dir.glob("runs/*.json")) + sorted(study_dir.glob("sac-wire/runs/*.json"))
    rows = [json.loads(p.read_text()) for p in found]
    return sorted(
        (r for r in rows if r["trials"] == trials and r["task"] == "baselines"),
        key=lambda r: (r["variant"], r["method"], r["seed"]),
    )


def _cpu_s() -> float:
    """CPU seconds of this process and its finished child processes (the study's workers)."""
    import resource

    own, children = (resource.getrusage(resource.RUSAGE_SELF),
                     resource.getrusage(resource.RUSAGE_CHILDREN))
    return own.ru_utime + own.ru_stime + children.ru_utime + children.ru_stime


def _curves(study_dir: Path, run_id: str) -> dict[str, np.ndarray]:
    """A run's per-trial curves, from the study folder or its SAC-on-wires sub-study."""
    from forcelearn.tools.study.runner import load_curves

    for folder in (study_dir, study_dir / "sac-wire"):
        if (folder / "runs" / f"{run_id}.npz").exists():
            return load_curves(folder, run_id)
    return load_curves(study_dir, run_id)


def main(argv: list[str] | None = None) -> int:
    """Run the comparison study and write docs/results/baselines.md with its figure."""
    from forcelearn.tools.study.runner import run_study
    from forcelearn.tools.study.tasks import get_task

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=10)
    parser.add_argument("--trials", type=int, default=300)
    parser.add_argument("--methods", default="srv,pi,ilc,cma,sac")
    parser.add_argument("--vec-methods", default="cma,sac",
                        help="the methods run on a numpy cell of SurfaceVec-v0")
    parser.add_argument("--srv-starts", default="probe,cold", help="srv's learner_start values")
    parser.add_argument("--sac-wire-seeds", type=int, default=3,
                        help="seeds of SAC on Surface-v0, default variant (0: none)")
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
    on_vec = set(args.vec_methods.split(",")) if args.vec_methods else set()
    points = [
        {"method": m, "variant": v, "env": "vec" if m in on_vec else "wire",
         "learner_start": start}
        for v in variants for m in methods
        for start in (args.srv_starts.split(",") if m == "srv" else ["probe"])
    ]
    command = (
        "python -m forcelearn.tools.results.baselines_report "
        f"--seeds {args.seeds} --trials {args.trials} --methods {args.methods} "
        f"--vec-methods {args.vec_methods} --srv-starts {args.srv_starts} "
        f"--variants {args.variants} --sac-wire-seeds {args.sac_wire_seeds}"
    )
    workers = args.workers or os.cpu_count() or 1
    started, cpu_started = time.perf_counter(), _cpu_s()
    if args.report_only:
        rows = saved_rows(args.study_dir, args.trials)
        header = f"Tabulated from the runs saved in `{args.study_dir}` by `{command}`"
    else:
        outcome = run_study(get_task("baselines"), args.study_dir, args.trials,
                            range(args.seeds), points, workers=workers, command=command)
        rows, ran, reused = outcome.rows, outcome.ran, outcome.reused
        if args.sac_wire_seeds and "sac" in methods:
            wire_sac = [{"method": "sac", "variant": "default", "env": "wire",
                         "learner_start": "probe"}]
            extra = run_study(get_task("baselines"), args.study_dir / "sac-wire", args.trials,
                              range(args.sac_wire_seeds), wire_sac, workers=workers,
                              command=command)
            rows, ran, reused = rows + extra.rows, ran + extra.ran, reused + extra.reused
        header = (
            f"Made by `{command}` ({time.perf_counter() - started:.0f} s wall, "
            f"{_cpu_s() - cpu_started:.0f} s CPU of this process and its workers, "
            f"{workers} workers, {ran} runs run now, {reused} reused)"
        )
    curves = {r["run_id"]: _curves(args.study_dir, r["run_id"]) for r in rows}
    args.out.mkdir(parents=True, exist_ok=True)
    figure = args.out / "baselines_learning_curves.png"
    learning_curves_figure(rows, curves, args.trials, figure)
    table = report_rows(rows, args.trials)
    (args.out / "baselines_table.md").write_text(header + ".\n\n" + "\n".join(table) + "\n")
    print("\n".join(table))
    print(f"wrote {figure} and {args.out / 'baselines_table.md'}")
    print(f"budget rule: stop at converged + {CONVERGENCE_WINDOW} + {AFTER_CONVERGED} trials")
    print(header)
    return 0


if __name__ == "__main__":
    sys.exit(main())
