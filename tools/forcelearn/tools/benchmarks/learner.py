"""Benchmark: SRV learner steps per second (act + learn) on the paper's 2-D grid.

Generalized phase, grid 100 x 200 (θ1, θ2 of §4), d = 5 (121 boxes per update),
two outputs. Inputs wander over the grid as a random walk so the neighbourhood
is clipped at edges as often as it is in a real run. ``--batch B`` times the
batched learner (B members stepped together) and prints the aggregate rate.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from forcelearn.learning import BoxGrid, Dimension, SRVLearner, SRVParams
from forcelearn.learning.batched import BatchedSRVLearner

GRID = BoxGrid(
    [Dimension("theta1_deg", 30.0, 60.0, 100), Dimension("theta2_deg", -75.0, -15.0, 200)]
)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``forcelearn bench learner``."""
    parser.add_argument("--steps", type=int, default=200_000, help="steps to time (default 200000)")
    parser.add_argument("--repeats", type=int, default=3, help="timed repeats; best is shown")
    parser.add_argument("--seed", type=int, default=0, help="random seed")
    parser.add_argument(
        "--batch", type=int, default=0, help="time the batched learner with this many members"
    )


def _inputs(steps: int, seed: int, width: int) -> tuple[np.ndarray, np.ndarray]:
    """Random-walk inputs (steps, width, 2) in degrees and evaluations (steps, width)."""
    rng = np.random.default_rng(seed + 1)
    walk = np.cumsum(rng.normal(0.0, 0.5, size=(steps, width, 2)), axis=0)
    xs = np.stack(
        [45.0 + 15.0 * np.sin(walk[..., 0] / 20.0), -45.0 + 30.0 * np.sin(walk[..., 1] / 20.0)],
        axis=-1,
    )
    return xs, rng.uniform(0.0, 1.0, size=(steps, width))


def measure(steps: int, seed: int = 0) -> float:
    """Return single-learner steps per second over ``steps`` act+learn pairs."""
    learner = SRVLearner(GRID, n_outputs=2, params=SRVParams(), rng=seed)
    xs, rs = _inputs(steps, seed, 1)
    inputs = xs[:, 0].tolist()
    start = time.perf_counter()
    for x, r in zip(inputs, rs[:, 0].tolist(), strict=True):
        learner.learn(learner.act(x), r)
    return steps / (time.perf_counter() - start)


def measure_batch(steps: int, batch: int, seed: int = 0) -> float:
    """Return aggregate member steps per second of a ``batch``-member learner."""
    learner = BatchedSRVLearner(GRID, 2, [SRVParams()] * batch, list(range(seed, seed + batch)))
    rounds = max(1, steps // batch)
    xs, rs = _inputs(rounds, seed, batch)
    members = np.arange(batch)
    start = time.perf_counter()
    for k in range(rounds):
        learner.learn(learner.act(members, xs[k]), rs[k])
    return rounds * batch / (time.perf_counter() - start)


def run(args: argparse.Namespace) -> int:
    """Print steps/s for each repeat and the best one."""
    what = f"batched learner, {args.batch} members" if args.batch else "SRV learner"
    target = "100,000 aggregate" if args.batch else "20,000"
    print(
        f"{what}, generalized phase, grid 100x200, d=5 (121 boxes), 2 outputs, {args.steps} steps"
    )
    results = []
    for i in range(args.repeats):
        if args.batch:
            rate = measure_batch(args.steps, args.batch, args.seed + i)
        else:
            rate = measure(args.steps, args.seed + i)
        results.append(rate)
        print(f"  repeat {i + 1}: {rate:,.0f} steps/s")
    print(f"best: {max(results):,.0f} steps/s  (target >= {target} steps/s on one core)")
    return 0
