"""The report of the baselines comparison: ``docs/results/baselines.md`` and its figure.

Runs the study of :mod:`.baselines_study` through the study runner (finished
runs are skipped) and writes the tables and the learning-curves figure::

    python -m forcelearn.tools.results.baselines_report [--seeds 10] [--methods srv,pi,ilc,cma]
        [--variants default,fast_wear,soft] [--trials 300] [--workers 2]
"""

from __future__ import annotations

import argparse
import math
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
    from forcelearn.tools.study.runner import load_curves, run_study
    from forcelearn.tools.study.tasks import get_task

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
        "python -m forcelearn.tools.results.baselines_report "
        f"--seeds {args.seeds} --trials {args.trials} "
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
