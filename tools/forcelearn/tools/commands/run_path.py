"""``forcelearn run`` of the path task (``[task] kind = "path"`` or ``--path FILE``; docs/path.md).

Reads and checks the path before the cell opens, runs the probe pass and the
passes (:mod:`forcelearn.tools.experiments.path_run`), prints a progress line
per pass (unless ``--no-progress``) and the end lines (or ``--json``: the
summary).
"""

from __future__ import annotations

import argparse
import sys
import time
import tomllib
from pathlib import Path

from forcelearn.run_output import summary_text
from forcelearn.site import load_cell_config
from forcelearn.tools.experiments.path_run import DEFAULT_PASSES, end_lines, run_path
from forcelearn.trainer import TrialRecord


def is_path_run(args: argparse.Namespace) -> bool:
    """True when this ``forcelearn run`` is the path task's (``--path`` or ``[task] kind``)."""
    if getattr(args, "path", None) is not None:
        return True
    if args.config is None or args.resume is not None:
        return False
    try:
        with open(args.config, "rb") as handle:
            table = tomllib.load(handle).get("task", {})
    except (OSError, tomllib.TOMLDecodeError):
        return False  # the §5 loader reports it, naming the file
    return isinstance(table, dict) and table.get("kind") == "path"


def run(args: argparse.Namespace) -> int:
    """Run the path task as ``forcelearn run``'s options say."""
    if args.resume is not None:
        print("forcelearn run: --resume is not available for the path task yet: start the run "
              "again (the probe pass gives the warm start)", file=sys.stderr)
        return 2
    config = load_cell_config(args.config, task_path=args.path)
    passes = args.trials or (config.trials if _run_trials_given(args.config) else DEFAULT_PASSES)
    seed = config.seed if args.seed is None else args.seed
    out = args.out or Path("runs") / time.strftime("path-%Y%m%d-%H%M%S")

    def progress(record: TrialRecord) -> None:
        if not args.no_progress:
            print(f"pass {record.index + 1}/{passes}: {record.phase[:4]}, {record.steps} points, "
                  f"force RMS {record.force_rms_n:.2f} N", file=sys.stderr)

    summary = run_path(config, out, passes, seed, on_pass=progress)
    if args.json:
        print(summary_text(summary), end="")
    else:
        print("\n".join(end_lines(summary, out)))
    if not summary["in_band_at_end"]:
        print(f"forcelearn run: NOT IN BAND AT THE END: {summary['diagnosis']}", file=sys.stderr)
        return 3 if args.require_converged else 0
    return 0


def _run_trials_given(config: Path | None) -> bool:
    """True when the config file sets ``[run] trials`` (else the path task's default)."""
    if config is None:
        return False
    with open(config, "rb") as handle:
        return "trials" in tomllib.load(handle).get("run", {})
