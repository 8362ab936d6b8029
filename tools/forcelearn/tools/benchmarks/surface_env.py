"""``forcelearn bench surface-env``: Gymnasium ``forcelearn/Surface-v0`` steps per second.

Opens the env on the emulated cell (the real drivers, one simulated clock),
resets it once with a seed (that opens the cell and runs the probe: not
timed), then steps it with a constant action for ``--seconds`` of wall time,
resetting without a seed (the cell and its wear are kept) at every episode's
end. Prints steps/s and episodes; ``forcelearn bench all`` shows it beside
the pty echo floor.
"""

from __future__ import annotations

import argparse
import time
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class EnvRate:
    """Steps per second of one timed stretch."""

    steps: int
    episodes: int
    wall_s: float

    @property
    def steps_per_s(self) -> float:
        """Env steps per wall second."""
        return self.steps / self.wall_s


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``forcelearn bench surface-env``."""
    parser.add_argument("--seconds", type=float, default=10.0, help="wall time stepped (s)")
    parser.add_argument("--action", type=float, default=0.0, help="the constant action in [-1, 1]")
    parser.add_argument("--seed", type=int, default=0, help="the first reset's seed")


def measure(seconds: float, action: float = 0.0, seed: int = 0) -> EnvRate:
    """Step ``Surface-v0`` for ``seconds`` of wall time after an untimed seeded reset."""
    import gymnasium

    import forcelearn.envs  # noqa: F401  (registers the ids)

    env = gymnasium.make("forcelearn/Surface-v0")
    try:
        env.reset(seed=seed)
        act = np.array([action])
        steps = episodes = 0
        start = time.perf_counter()
        while (elapsed := time.perf_counter() - start) < seconds:
            _, _, terminated, truncated, _ = env.step(act)
            steps += 1
            if terminated or truncated:
                episodes += 1
                env.reset()
    finally:
        env.close()
    return EnvRate(steps, episodes, elapsed)


def run(args: argparse.Namespace) -> int:
    """Print steps/s and episodes."""
    rate = measure(args.seconds, args.action, args.seed)
    print(f"forcelearn/Surface-v0, action {args.action}: {rate.steps_per_s:,.1f} steps/s "
          f"({rate.steps} steps, {rate.episodes} episodes in {rate.wall_s:.1f} s)")
    return 0
