"""``forcelearn run``: learn force tracking on the cell (paper §5), emulated by default.

With no ``--config`` the built-in emulated cell starts in-process: the
robot-controller emulator on a pty and the JR3 emulator on a virtual CAN bus,
reached through the real drivers. ``--config site.toml`` runs the same
controller on a real cell. Ctrl-C stops the robot; the last whole trial is
checkpointed, and ``--resume DIR`` continues from it. Every run appends its
steps and trials to ``live.ndjson`` (``forcelearn view DIR`` follows it);
``--live`` also serves a read-only page of the run (docs/live.md). A run
ends with a few lines (the verdict, the final force against the band, the
figures and where they are); ``--json`` prints the whole summary instead, for
scripts. docs/run-directory.md describes the run directory.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

from tqdm import tqdm

from forcelearn.learning import SRVLearner
from forcelearn.run_output import summary_text
from forcelearn.tools.commands.run_path import is_path_run
from forcelearn.tools.commands.run_path import run as run_path
from forcelearn.tools.experiments.surface_outputs import end_lines
from forcelearn.tools.experiments.surface_run import execute
from forcelearn.tools.experiments.surface_state import prepare_run
from forcelearn.tools.live.publish import LivePublisher, surface_extras, surface_meta
from forcelearn.tools.live.session import add_live_arguments, live_run
from forcelearn.trainer import TrialRecord

NOT_CONVERGED = 3
"""Exit status under ``--require-converged`` of a run that did not end in band (unconverged,
or converged and out of band at its end)."""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``forcelearn run``."""
    parser.add_argument("--config", type=Path, help="cell config TOML (default: emulated cell)")
    parser.add_argument("--trials", type=int,
                        help="total trials of the run (default 300; the path task: passes, 25)")
    parser.add_argument("--seed", type=int, help="random seed (default 0)")
    parser.add_argument("--out", type=Path, help="run directory (default runs/surface-<time>)")
    parser.add_argument("--resume", type=Path, metavar="DIR", help="continue the run in DIR")
    parser.add_argument("--path", type=Path, metavar="FILE",
                        help="run the path task over this taught path (CSV or RAPID module; "
                        "docs/path.md) instead of [task]'s")
    parser.add_argument("--no-progress", action="store_true", help="no progress bar")
    parser.add_argument(
        "--json", action="store_true", help="end by printing the summary as JSON (for scripts)"
    )
    parser.add_argument(
        "--require-converged",
        action="store_true",
        help=f"exit with status {NOT_CONVERGED} when the run did not end in band "
        "(not converged, or out of band over its last 10 trials)",
    )
    add_live_arguments(parser)


def run(args: argparse.Namespace) -> int:
    """Run or resume the surface experiment and write its run directory."""
    if is_path_run(args):  # [task] kind = "path" or --path: the path task's own run
        return run_path(args)
    if args.resume and (args.config or args.out or args.seed is not None):
        print(
            "forcelearn run: --resume takes the run's own config, seed and folder; "
            "give only --resume DIR (and optionally --trials)",
            file=sys.stderr,
        )
        return 2
    if args.trials is not None and args.trials < 1:
        print("forcelearn run: --trials must be >= 1", file=sys.stderr)
        return 2
    out = args.resume or args.out or Path("runs") / time.strftime("surface-%Y%m%d-%H%M%S")
    surface_run, checkpoint = prepare_run(
        args.config, out, args.trials, args.seed, resume=args.resume is not None
    )
    done = len(surface_run.result.records) if checkpoint is None else None
    bar = tqdm(
        total=surface_run.trials,
        unit="trial",
        disable=args.no_progress,
        dynamic_ncols=True,
        initial=done or 0,
    )

    cell_s = sum(r.cell_time_s for r in surface_run.result.records)
    meta = surface_meta(surface_run.config, surface_run.trials)
    live = live_run(meta, args, out, surface_extras(surface_run))

    def warn(publisher: LivePublisher, text: str) -> None:
        bar.write(f"forcelearn run: WARNING {text}", sys.stderr)
        publisher.event("Warning", text)

    def progress(record: TrialRecord, learner: SRVLearner) -> None:
        nonlocal cell_s
        cell_s += record.cell_time_s
        publisher.on_trial(record, learner)
        if bar.n < record.index:
            bar.update(record.index - bar.n)
        bar.update(1)
        bar.set_postfix(
            phase=record.phase[:4],
            steps=record.steps,
            rms_n=f"{record.force_rms_n:.2f}",
            cell=_clock(cell_s),
        )

    try:
        with bar, live as publisher:
            summary = execute(
                surface_run,
                checkpoint,
                on_trial=progress,
                on_step=publisher.on_step,
                on_warning=lambda text: warn(publisher, text),
            )
            if summary["diagnosis"]:  # the end verdict on the live page and in the journal
                publisher.event("Diagnosis", summary["diagnosis"])
    except KeyboardInterrupt:
        print(
            f"\nforcelearn run: interrupted; the robot was stopped and the last whole trial "
            f"is saved. Continue with: forcelearn run --resume {out}",
            file=sys.stderr,
        )
        return 130
    if args.json:
        print(summary_text(summary), end="")
    else:
        print("\n".join(end_lines(summary, out)))
        if args.live:
            print(f"see the run again with: forcelearn view {out}")
    if not (summary["converged"] and summary["in_band_at_end"]):
        verdict = "NOT CONVERGED" if not summary["converged"] else "NOT IN BAND AT THE END"
        why = f": {summary['diagnosis']}" if args.json else " (the diagnosis is above)"
        print(f"forcelearn run: {verdict}{why}", file=sys.stderr)
        return NOT_CONVERGED if args.require_converged else 0
    return 0


def _clock(seconds: float) -> str:
    """Cell time as h:mm:ss (the robot's clock; what the run would hold a real cell)."""
    whole = int(seconds)
    return f"{whole // 3600}:{whole % 3600 // 60:02d}:{whole % 60:02d}"
