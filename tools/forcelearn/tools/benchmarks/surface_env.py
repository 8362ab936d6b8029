"""``forcelearn bench surface-env``: Gymnasium ``forcelearn/Surface-v0`` steps per second.

Opens the env on the emulated cell (the real drivers, one simulated clock),
resets it once with a seed (that opens the cell and runs the probe: not
timed), then steps it with a constant action for ``--seconds`` of wall time,
resetting without a seed (the cell and its wear are kept) at every episode's
end. Prints steps per wall second and per CPU second of the process, and
episodes; ``forcelearn bench all`` shows both beside the pty echo floor.
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
    cpu_s: float
    """This process's CPU time over the stretch, s (a shared machine disturbs it far less)."""

    @property
    def steps_per_s(self) -> float:
        """Env steps per wall second."""
        return self.steps / self.wall_s

    @property
    def steps_per_cpu_s(self) -> float:
        """Env steps per CPU second of this process."""
        return self.steps / self.cpu_s


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
        start, cpu_start = time.perf_counter(), time.process_time()
        while (elapsed := time.perf_counter() - start) < seconds:
            _, _, terminated, truncated, _ = env.step(act)
            steps += 1
            if terminated or truncated:
                episodes += 1
                env.reset()
        cpu = time.process_time() - cpu_start
    finally:
        env.close()
    return EnvRate(steps, episodes, elapsed, cpu)


def run(args: argparse.Namespace) -> int:
    """Print steps/s and episodes."""
    rate = measure(args.seconds, args.action, args.seed)
    print(f"forcelearn/Surface-v0, action {args.action}: {rate.steps_per_s:,.1f} steps/s, "
          f"{rate.steps_per_cpu_s:,.1f} per CPU s ({rate.steps} steps, {rate.episodes} "
          f"episodes in {rate.wall_s:.1f} s, {rate.cpu_s:.1f} s CPU)")
    return 0
