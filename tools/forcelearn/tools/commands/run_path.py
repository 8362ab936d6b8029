"""``forcelearn run`` of the path task (``[task] kind = "path"`` or ``--path FILE``; docs/path.md).

Reads and checks the path before the cell opens, runs the probe pass and the
passes (:mod:`forcelearn.tools.experiments.path_run`), prints a progress line
per pass (unless ``--no-progress``) and the end lines (or ``--json``: the
summary). ``--resume DIR`` continues a path run from its last whole pass (the
config file must be as it was); every run appends its steps and passes to
``live.ndjson`` (``forcelearn view DIR``) and ``--live`` serves the page.
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
import time
import tomllib
from pathlib import Path

import numpy as np

from forcelearn.errors import StateFileError
from forcelearn.learning import SRVLearner, load_learner
from forcelearn.run_output import summary_text
from forcelearn.tools.experiments.path_run import DEFAULT_PASSES, end_lines, execute, load_path
from forcelearn.tools.experiments.path_state import CHECKPOINT, PathRun, prepare_path_run
from forcelearn.tools.live.publish import RowExtras, surface_meta
from forcelearn.tools.live.session import live_run
from forcelearn.trainer import TrialRecord


def is_path_run(args: argparse.Namespace) -> bool:
    """True when this ``forcelearn run`` is the path task's (``--path`` or ``[task] kind``)."""
    if getattr(args, "path", None) is not None:
        return True
    if args.resume is not None:
        return _checkpoint_task(args.resume / CHECKPOINT) == "path"
    if args.config is None:
        return False
    try:
        with open(args.config, "rb") as handle:
            table = tomllib.load(handle).get("task", {})
    except (OSError, tomllib.TOMLDecodeError):
        return False  # the §5 loader reports it, naming the file
    return isinstance(table, dict) and table.get("kind") == "path"


def run(args: argparse.Namespace) -> int:
    """Run (or resume) the path task as ``forcelearn run``'s options say."""
    resume = args.resume is not None
    if resume and (args.config or args.out or args.seed is not None or args.path):
        print("forcelearn run: --resume takes the run's own config, path, seed and folder; "
              "give only --resume DIR (and optionally --trials)", file=sys.stderr)
        return 2
    given = None if resume else (args.trials or (
        None if _run_trials_given(args.config) else DEFAULT_PASSES))
    out = args.resume or args.out or Path("runs") / time.strftime("path-%Y%m%d-%H%M%S")
    try:
        path_run, state = prepare_path_run(args.config, args.path, out, args.trials or given,
                                           args.seed, DEFAULT_PASSES, resume)
    except StateFileError as exc:
        print(f"forcelearn run: {exc}", file=sys.stderr)
        return 2
    if not resume and path_run.config.trials and given is None:
        path_run.trials = path_run.config.trials  # [run] trials of the config
    passes = path_run.trials
    points = len(load_path(path_run.config))
    meta = dataclasses.replace(surface_meta(path_run.config, passes), task="path",
                               steps_per_trial=points)

    def progress(record: TrialRecord, learner: SRVLearner) -> None:
        publisher.on_trial(record, learner)
        if not args.no_progress:
            print(f"pass {record.index + 1}/{passes}: {record.phase[:4]}, {record.steps} points, "
                  f"force RMS {record.force_rms_n:.2f} N", file=sys.stderr)

    try:
        with live_run(meta, args, out, path_extras(path_run)) as publisher:
            summary = execute(path_run, state, on_pass=progress, on_step=publisher.on_step)
            if summary["diagnosis"]:
                publisher.event("Diagnosis", summary["diagnosis"])
    except KeyboardInterrupt:
        print(f"\nforcelearn run: interrupted; the robot was stopped and the last whole pass "
              f"is saved. Continue with: forcelearn run --resume {out}", file=sys.stderr)
        return 130
    if args.json:
        print(summary_text(summary), end="")
    else:
        print("\n".join(end_lines(summary, out)))
    if not summary["in_band_at_end"]:
        print(f"forcelearn run: NOT IN BAND AT THE END: {summary['diagnosis']}", file=sys.stderr)
        return 3 if args.require_converged else 0
    return 0


def path_extras(path_run: PathRun) -> RowExtras:
    """Adds each row's ``mean_offset_mm``: the learner's mean μ as an offset (mm)."""

    def extras(row: dict[str, float]) -> dict[str, float]:
        task = path_run.task
        output = task.output if task is not None else None
        if output is None:
            return {}
        mean = np.array([row["mean_0"]])
        return {"mean_offset_mm": float(output(mean, np.array([row.get("point", 0.0)]))[0])}

    return extras


def _checkpoint_task(checkpoint: Path) -> str | None:
    """The task of a run directory's checkpoint (None: none, or unreadable)."""
    try:
        return str(load_learner(checkpoint)[1].get("task")) if checkpoint.exists() else None
    except StateFileError:
        return None


def _run_trials_given(config: Path | None) -> bool:
    """True when the config file sets ``[run] trials`` (else the path task's default)."""
    if config is None:
        return False
    with open(config, "rb") as handle:
        return "trials" in tomllib.load(handle).get("run", {})
