"""Paper §5 over seeds: `forcelearn run` with the defaults on the emulated cell, 10 seeds.

A thin call of the study runner behind ``forcelearn study surface`` (one
emulated-cell run per seed, resumable in ``--study-dir``); writes
``docs/results/surface.md`` (trials to the global criterion and to convergence,
final force RMS, wall time, steps per second) and the figures of seed 0, run
once more into a scratch folder (runs are deterministic, so it is the same run).

Usage::

    python -m forcelearn.tools.results.surface [--seeds 10] [--trials 300] [--workers 2]
"""

from __future__ import annotations

import argparse
import os
import shutil
import sys
import tempfile
import time
from pathlib import Path

from forcelearn.run_output import median_range
from forcelearn.tools.experiments.surface_run import execute
from forcelearn.tools.experiments.surface_state import prepare_run
from forcelearn.tools.study.runner import run_study
from forcelearn.tools.study.tasks import get_task

PAPER_REPETITIONS = 237


def main(argv: list[str] | None = None) -> int:
    """Run the seeds and write the report."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=10)
    parser.add_argument("--trials", type=int, default=300)
    parser.add_argument("--workers", type=int, help="local processes (default: all cores)")
    parser.add_argument("--scheduler", help="Dask scheduler address (forcelearn[cluster])")
    parser.add_argument("--out", type=Path, default=Path("docs/results"))
    parser.add_argument("--study-dir", type=Path, default=Path("runs/study-surface"))
    args = parser.parse_args(argv)
    args.out.mkdir(parents=True, exist_ok=True)
    started = time.perf_counter()
    command = (
        f"python -m forcelearn.tools.results.surface --seeds {args.seeds} --trials {args.trials}"
    )
    outcome = run_study(
        get_task("surface"),
        args.study_dir,
        args.trials,
        range(args.seeds),
        [{}],
        workers=args.workers,
        scheduler=args.scheduler,
        command=command,
    )
    summaries = outcome.rows
    with tempfile.TemporaryDirectory() as folder:
        run, checkpoint = prepare_run(None, Path(folder) / "seed0", args.trials, 0, resume=False)
        execute(run, checkpoint)
        for name in ("fig12_positions.png", "fig13_contact_force.png", "fig14_initial_force.png"):
            shutil.copyfile(Path(folder) / "seed0" / name, args.out / f"surface_{name}")
    wall = time.perf_counter() - started
    budget = args.trials
    converged = [s["converged_trial"] for s in summaries]
    reached = [s["criterion_trial"] for s in summaries]
    lines = [
        "# Force tracking on the sponge (paper §5), emulated cell",
        "",
        f"Made by `{command}` ({wall:.0f} s, {args.workers or os.cpu_count()} runs in "
        "parallel on a 2-core machine; the runs are `forcelearn study surface` runs).",
        "Each seed is a whole `forcelearn run` with the defaults: the robot-controller",
        "emulator on a pty and the JR3 emulator on a virtual CAN bus, reached through the",
        "real drivers; desired force 2 kgf = 19.61 N, 20 steps of −5 mm, γ = 0.8,",
        "α = β = 0.5 generalized, α = 1 / β = 0.5 specialized, N = 10.",
        "Converged: 10 complete trials in a row, each with force RMS ≤ 5 % (0.98 N).",
        "Trial numbers count from 0; a seed that never converges counts as the budget.",
        "",
        "| figure | median (range) |",
        "|---|---|",
        f"| seeds converged | {sum(c is not None for c in converged)} / {len(summaries)} |",
        f"| trials to converge (paper: ~{PAPER_REPETITIONS}) | "
        f"{median_range([budget if c is None else c for c in converged], '{:.0f}')} |",
        f"| trials to the global criterion | "
        f"{median_range([budget if c is None else c for c in reached], '{:.0f}')} |",
        f"| final force RMS, median of the last 50 trials (N) | "
        f"{median_range([s['final_force_rms_n'] for s in summaries], '{:.3f}')} |",
        f"| failed trials | {median_range([s['failures'] for s in summaries], '{:.0f}')} |",
        f"| wall time per run (s) | {median_range([s['wall_s'] for s in summaries], '{:.1f}')} |",
        f"| controller steps per second through the wire stack | "
        f"{median_range([s['steps_per_s'] for s in summaries], '{:.0f}')} |",
        "",
        "Seed 0's run: Y commands (Fig. 12), contact force at the first trial, mid-way",
        "and at the end (Fig. 13), initial contact force as the sponge wears (Fig. 14).",
        "",
        "![Fig. 12](surface_fig12_positions.png)",
        "",
        "![Fig. 13](surface_fig13_contact_force.png)",
        "",
        "![Fig. 14](surface_fig14_initial_force.png)",
        "",
    ]
    (args.out / "surface.md").write_text("\n".join(lines))
    print(f"wrote {args.out / 'surface.md'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
