"""Benchmark: the cost of one step of the baselines study, per method, on the emulated cell.

Runs a method of :mod:`.baselines_study` (``run_baseline``: ``forcelearn/Surface-v0``
on the emulated cell through the real drivers, the surface probe first) twice for
one seed: ``--short`` trials, then ``--long`` trials. The difference between the
two removes what every run pays once (opening the cell, the probe, imports), so
the figure is what each further step costs: CPU time (this process) and wall
time, in ms per step. The study's wall time is about its steps times the wall
time per step, divided by the workers. The figures depend on the host's load;
run it on an idle machine.
"""

from __future__ import annotations

import argparse
import time

from forcelearn.tools.baselines_study import METHODS, BaselinesConfig, run_baseline


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``forcelearn bench baselines``."""
    parser.add_argument("--methods", default="pi,cma",
                        help="comma-separated methods (srv, pi, ilc, cma; default pi,cma)")
    parser.add_argument("--variant", default="default", help="cell variant (default: default)")
    parser.add_argument("--short", type=int, default=5, help="trials of the short run")
    parser.add_argument("--long", type=int, default=25, help="trials of the long run")
    parser.add_argument("--seed", type=int, default=1, help="seed of both runs")


def _timed_run(method: str, variant: str, trials: int, seed: int) -> tuple[float, float, int]:
    """(CPU s, wall s, steps) of one run."""
    cpu, wall = time.process_time(), time.perf_counter()
    summary, _ = run_baseline(BaselinesConfig(method=method, variant=variant, trials=trials),
                              seed)
    return time.process_time() - cpu, time.perf_counter() - wall, int(summary["steps"])


def run(args: argparse.Namespace) -> int:
    """Print CPU and wall ms per step of each method (long run minus short run)."""
    methods = [m.strip() for m in args.methods.split(",") if m.strip()]
    unknown = [m for m in methods if m not in METHODS or m == "sac"]
    if unknown or not 0 < args.short < args.long:
        raise SystemExit(
            f"bench baselines: methods from srv, pi, ilc, cma (got {', '.join(unknown) or '-'}), "
            f"and 0 < --short < --long (got {args.short}, {args.long})"
        )
    _timed_run(methods[0], args.variant, 1, args.seed)  # imports and first-use caches
    for method in methods:
        cpu_a, wall_a, steps_a = _timed_run(method, args.variant, args.short, args.seed)
        cpu_b, wall_b, steps_b = _timed_run(method, args.variant, args.long, args.seed)
        steps = steps_b - steps_a
        if steps <= 0:
            print(f"{method}: the long run made no more steps than the short one; no figure")
            continue
        print(
            f"{method} ({args.variant}, seed {args.seed}): {steps} steps in trials "
            f"{args.short}..{args.long - 1}: {1000 * (cpu_b - cpu_a) / steps:.2f} ms CPU, "
            f"{1000 * (wall_b - wall_a) / steps:.2f} ms wall per step"
        )
    return 0
