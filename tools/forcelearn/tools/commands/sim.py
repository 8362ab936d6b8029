"""``forcelearn sim contour``: the paper's §4 simulation, written to a run directory.

Outputs in ``--out`` (default ``runs/contour-seed<S>``): summary.json, trials.csv,
steps_switch.csv and steps_final.csv (step logs at the phase switch and at the
last trial), the learner state (learner.npz) and the PNG figures of Figs. 5-10.
"""

from __future__ import annotations

import argparse
import json
import sys
from dataclasses import replace
from pathlib import Path

from tqdm import tqdm

from forcelearn.learning import SRVLearner, save_learner
from forcelearn.run_output import write_step_log, write_summary, write_trials
from forcelearn.tools.experiments.contour import load_config, run_contour
from forcelearn.tools.figures import contour as figures_contour
from forcelearn.tools.live.publish import contour_meta
from forcelearn.tools.live.session import add_live_arguments, live_run
from forcelearn.trainer import TrialLog, TrialRecord


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``forcelearn sim``."""
    sub = parser.add_subparsers(dest="simulation", metavar="SIMULATION", required=True)
    contour = sub.add_parser(
        "contour",
        help="two-link arm tracks force along a circular surface (paper §4)",
        description="Learn contour force tracking with the two-link arm of paper §4.",
    )
    contour.add_argument("--trials", type=int, help="number of trials (default 4000)")
    contour.add_argument("--seed", type=int, help="random seed (default 0)")
    contour.add_argument(
        "--specialized-only", action="store_true", help="skip the generalized phase (ablation)"
    )
    contour.add_argument("--out", type=Path, help="run directory (default runs/contour-seed<S>)")
    contour.add_argument("--config", type=Path, help="TOML file: [learner] [task] [geometry] [run]")
    contour.add_argument("--no-figures", action="store_true", help="skip the PNG figures")
    contour.add_argument("--no-progress", action="store_true", help="no progress bar")
    contour.add_argument(
        "--require-converged",
        action="store_true",
        help="exit with status 3 when the run ends unconverged",
    )
    add_live_arguments(contour)


def run(args: argparse.Namespace) -> int:
    """Run the contour simulation and write its run directory."""
    config = load_config(args.config, {"trials": args.trials, "seed": args.seed})
    if args.specialized_only:
        config = replace(config, learner=replace(config.learner, generalized_phase=False))
    out = args.out or Path("runs") / f"contour-seed{config.seed}"
    out.mkdir(parents=True, exist_ok=True)

    bar = tqdm(total=config.trials, unit="trial", disable=args.no_progress, dynamic_ncols=True)

    def progress(record: TrialRecord, log: TrialLog, learner: SRVLearner) -> None:
        publisher.on_trial(record, learner)
        bar.update(1)
        if record.index % 10 == 0 or record.index == config.trials - 1:
            bar.set_postfix(
                phase=record.phase[:4], steps=record.steps, rms_n=f"{record.force_rms_n:.3f}"
            )

    # No journal: a contour run is seconds of pure simulation (view reads its CSVs).
    with bar, live_run(contour_meta(config), args, None) as publisher:
        on_step = publisher.on_step if args.live else None
        done = run_contour(config, on_trial=progress, on_step=on_step)
    result = done.result
    write_summary(out, done.summary)
    write_trials(out, result.records)
    if result.switch_log is not None:
        write_step_log(out / "steps_switch.csv", result.switch_log)
    if result.last_log is not None:
        write_step_log(out / "steps_final.csv", result.last_log)
    save_learner(done.learner, out / "learner.npz", metadata={"task": "contour"})
    if not args.no_figures:
        figures_contour.write_all(result, config.geometry, done.task.steps_per_trial, out)
    print(json.dumps(done.summary, indent=2))
    print(f"run directory: {out}")
    if not done.summary["converged"]:
        print(
            f"forcelearn sim contour: NOT CONVERGED in {config.trials} trials (no 10 complete "
            "trials in a row within 5 % force RMS); try more trials (--trials)",
            file=sys.stderr,
        )
        return 3 if args.require_converged else 0
    return 0
