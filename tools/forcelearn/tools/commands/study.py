r"""``forcelearn study TASK``: a grid of settings × seeds, on local cores or a Dask cluster.

Example::

    forcelearn study contour --seeds 10 --trials 4000 \\
        --set learner.gamma=0.7,0.8,0.9,0.95 --set d=2,3,5,8 --out runs/gamma-d

Each point of the product of the ``--set`` lists, for seeds 0..N−1, is one
run. Outputs in ``--out``: runs/<run_id>.json (one per finished run; a restarted
study skips these), runs.csv, summary.csv, summary.md, heatmap_<x>__<y>.png.
docs/studies.md tells the whole story.
"""

from __future__ import annotations

import argparse
import shlex
import sys
from pathlib import Path

from forcelearn.tools.study.grid import grid_points, leaf_keys, parse_sets
from forcelearn.tools.study.runner import DEFAULT_BATCH, run_study
from forcelearn.tools.study.tasks import TASKS, get_task


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``forcelearn study``."""
    parser.add_argument("task", choices=sorted(TASKS), help="what one run is")
    parser.add_argument("--seeds", type=int, default=10, help="seeds 0..N-1 per point (10)")
    parser.add_argument(
        "--set",
        dest="sets",
        action="append",
        default=[],
        metavar="KEY=V1,V2",
        help="sweep a config key over values; repeat for a product grid",
    )
    parser.add_argument("--trials", type=int, help="trials per run (default: the task's)")
    parser.add_argument("--out", type=Path, help="study folder (default runs/study-TASK)")
    parser.add_argument("--workers", type=int, help="local processes (default: all cores)")
    parser.add_argument(
        "--scheduler",
        metavar="ADDRESS",
        help="run on a Dask cluster, e.g. tcp://10.0.0.5:8786 (forcelearn[cluster])",
    )
    parser.add_argument(
        "--batch",
        type=int,
        default=DEFAULT_BATCH,
        help=f"most runs per batch of a batched task ({DEFAULT_BATCH})",
    )
    parser.add_argument("--list-keys", action="store_true", help="print the --set keys and exit")
    parser.add_argument("--no-progress", action="store_true", help="no progress bar")


def run(args: argparse.Namespace) -> int:
    """Plan the grid, run what is not done yet, write the tables and figures."""
    task = get_task(args.task)
    base = task.base_config()
    if args.list_keys:
        for key, value in leaf_keys(base).items():
            print(f"{key} = {value!r}")
        return 0
    if args.seeds < 1 or (args.trials is not None and args.trials < 1) or args.batch < 1:
        print("forcelearn study: --seeds, --trials and --batch must be >= 1", file=sys.stderr)
        return 2
    trials = args.trials or int(base.trials)
    points = grid_points(parse_sets(base, args.sets))
    out = args.out or Path("runs") / f"study-{task.name}"
    command = "forcelearn study " + shlex.join(
        [task.name, "--seeds", str(args.seeds), "--trials", str(trials)]
        + [item for s in args.sets for item in ("--set", s)]
    )
    outcome = run_study(
        task,
        out,
        trials,
        range(args.seeds),
        points,
        args.workers,
        args.scheduler,
        args.batch,
        not args.no_progress,
        command,
    )
    print(f"{len(outcome.rows)} runs ({outcome.ran} run now, {outcome.reused} reused) in {out}")
    for path in outcome.files:
        print(f"  {path}")
    return 0
