"""Benchmark: SRV learner steps per second (act + learn) on the paper's 2-D grid.

Generalized phase, grid 100 x 200 (θ1, θ2 of §4), d = 5 (121 boxes per update),
two outputs. Inputs wander over the grid as a random walk so the neighbourhood
is clipped at edges as often as it is in a real run.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from forcelearn.learning import BoxGrid, Dimension, SRVLearner, SRVParams


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``forcelearn bench learner``."""
    parser.add_argument("--steps", type=int, default=200_000, help="steps to time (default 200000)")
    parser.add_argument("--repeats", type=int, default=3, help="timed repeats; best is shown")
    parser.add_argument("--seed", type=int, default=0, help="random seed")


def measure(steps: int, seed: int = 0) -> float:
    """Return learner steps per second over ``steps`` act+learn pairs."""
    grid = BoxGrid(
        [Dimension("theta1_deg", 30.0, 60.0, 100), Dimension("theta2_deg", -75.0, -15.0, 200)]
    )
    learner = SRVLearner(grid, n_outputs=2, params=SRVParams(), rng=seed)
    rng = np.random.default_rng(seed + 1)
    walk = np.cumsum(rng.normal(0.0, 0.5, size=(steps, 2)), axis=0)
    xs = np.column_stack(
        [45.0 + 15.0 * np.sin(walk[:, 0] / 20.0), -45.0 + 30.0 * np.sin(walk[:, 1] / 20.0)]
    )
    rs = rng.uniform(0.0, 1.0, size=steps)
    inputs = xs.tolist()
    start = time.perf_counter()
    for x, r in zip(inputs, rs.tolist(), strict=True):
        learner.learn(learner.act(x), r)
    return steps / (time.perf_counter() - start)


def run(args: argparse.Namespace) -> int:
    """Print steps/s for each repeat and the best one."""
    print(
        "SRV learner, generalized phase, grid 100x200, d=5 (121 boxes), 2 outputs, "
        f"{args.steps} steps"
    )
    results = []
    for i in range(args.repeats):
        rate = measure(args.steps, args.seed + i)
        results.append(rate)
        print(f"  repeat {i + 1}: {rate:,.0f} steps/s")
    print(f"best: {max(results):,.0f} steps/s  (target >= 20,000 steps/s on one core)")
    return 0
