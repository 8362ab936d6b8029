"""Benchmark: how fast the emulated cell runs against the time it simulates.

Runs the §5 job (``forcelearn run``'s code path: the real drivers on the
in-process ``forcelearn-robot://`` and ``forcelearn-jr3`` routes, the emulators
on one simulated clock) for a number of trials
and prints the cell time (the robot's clock: what the run would hold a real
cell), the wall time, their ratio (the real-time factor) and steps per second.
The figures depend on the host's load; run it on an idle machine.
"""

from __future__ import annotations

import argparse
import statistics
import tempfile
from pathlib import Path

from forcelearn.tools.experiments.surface_run import execute
from forcelearn.tools.experiments.surface_state import prepare_run


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``forcelearn bench cell``."""
    parser.add_argument("--trials", type=int, default=300, help="trials per run (default 300)")
    parser.add_argument("--repeats", type=int, default=1, help="runs; the median is shown")
    parser.add_argument("--seed", type=int, default=0, help="random seed")
    parser.add_argument("--config", type=Path, help="cell config TOML (default: emulated cell)")


def run(args: argparse.Namespace) -> int:
    """Run the job ``--repeats`` times and print cell time, wall time and their ratio."""
    factors, walls = [], []
    for repeat in range(args.repeats):
        with tempfile.TemporaryDirectory(prefix="forcelearn-bench-cell-") as tmp:
            surface_run, _ = prepare_run(args.config, Path(tmp), args.trials, args.seed, False)
            summary = execute(surface_run, None)
        factors.append(summary["realtime_factor"])
        walls.append(summary["wall_s"])
        print(
            f"run {repeat + 1}: {summary['trials']} trials, {summary['steps']} steps, cell time "
            f"{summary['cell_time_s']:.0f} s, wall {summary['wall_s']:.1f} s, real-time factor "
            f"{summary['realtime_factor']:.1f}, {summary['steps_per_s']:.0f} steps/s, "
            f"converged at trial {summary['converged_trial']}"
        )
    print(
        f"median of {args.repeats}: real-time factor {statistics.median(factors):.1f}, "
        f"wall {statistics.median(walls):.1f} s"
    )
    return 0
