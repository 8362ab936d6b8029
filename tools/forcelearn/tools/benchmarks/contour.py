"""Benchmark: controller steps per second of the §4 contour simulation, single or batched.

Runs the paper's defaults (two-phase, 100 x 200 grid, d = 5) for ``--trials``
trials per seed; ``--batch B`` runs B seeds through the batched learner and
cells and prints the aggregate rate (all members' steps over the wall time).
"""

from __future__ import annotations

import argparse
import time
from dataclasses import replace

from forcelearn.tools.experiments.contour import ContourConfig, run_contour
from forcelearn.tools.experiments.contour_batch import run_contour_batch


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``forcelearn bench contour``."""
    parser.add_argument("--trials", type=int, default=300, help="trials per seed (default 300)")
    parser.add_argument("--batch", type=int, default=64, help="seeds per batch; 0 = single run")
    parser.add_argument("--repeats", type=int, default=1, help="timed repeats; best is shown")


def measure(trials: int, batch: int, seed: int = 0) -> tuple[float, int]:
    """Return (aggregate controller steps/s, steps) of one single or batched run."""
    configs = [replace(ContourConfig(trials=trials), seed=seed + i) for i in range(max(batch, 1))]
    started = time.perf_counter()
    if batch:
        summaries, _ = run_contour_batch(configs)
        steps = sum(s["steps"] for s in summaries)
    else:
        steps = run_contour(configs[0]).summary["steps"]
    return steps / (time.perf_counter() - started), steps


def run(args: argparse.Namespace) -> int:
    """Print the rate of each repeat and the best one."""
    what = f"batched, {args.batch} seeds" if args.batch else "single run"
    print(f"contour simulation (§4 defaults), {what}, {args.trials} trials per seed")
    rates = []
    for i in range(args.repeats):
        rate, steps = measure(args.trials, args.batch, seed=i * max(args.batch, 1))
        rates.append(rate)
        print(f"  repeat {i + 1}: {rate:,.0f} controller steps/s ({steps} steps)")
    target = "  (target >= 100,000 aggregate on one core)" if args.batch else ""
    print(f"best: {max(rates):,.0f} controller steps/s{target}")
    return 0
