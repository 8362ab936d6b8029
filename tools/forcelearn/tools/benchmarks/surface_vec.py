"""``forcelearn bench surface-vec``: ``forcelearn/SurfaceVec-v0`` env steps per second.

N numpy cells on one core (the process's own thread; numpy's BLAS threads are
not used by its small arrays), stepped with random actions in [-1, 1] for
``--seconds`` of wall time; every sub-env resets itself at its episode's end
(Gymnasium's NEXT_STEP autoreset). The map is the configured one (no
wire-level probe: the physics per step is the same). Target: 100,000 env
steps/s at N = 64 (docs/performance.md); ``forcelearn bench all`` shows it beside the
numpy foam-law floor.
"""

from __future__ import annotations

import argparse
import time

import numpy as np


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``forcelearn bench surface-vec``."""
    parser.add_argument("--num-envs", type=int, default=64, help="cells stepped at once")
    parser.add_argument("--seconds", type=float, default=3.0, help="wall time stepped (s)")


def measure(num_envs: int, seconds: float, seed: int = 0) -> float:
    """Return env steps per second (all cells counted) over ``seconds`` of stepping."""
    from forcelearn.envs.surface_vec import Probed, SurfaceVecEnv
    from forcelearn.site import load_cell_config
    from forcelearn.tasks.surface_map import configured_map

    probed = Probed(configured_map(load_cell_config(None).task))
    envs = SurfaceVecEnv(num_envs, probed=probed)
    envs.reset(seed=seed)
    rng = np.random.default_rng(seed)
    actions = rng.uniform(-1.0, 1.0, (256, num_envs, 1))
    for k in range(20):  # warm up
        envs.step(actions[k])
    steps = 0
    start = time.perf_counter()
    while (elapsed := time.perf_counter() - start) < seconds:
        for k in range(64):
            envs.step(actions[(steps + k) % 256])
        steps += 64
    return steps * num_envs / elapsed


def run(args: argparse.Namespace) -> int:
    """Print env steps/s."""
    rate = measure(args.num_envs, args.seconds)
    print(f"forcelearn/SurfaceVec-v0, N = {args.num_envs}: {rate:,.0f} env steps/s "
          "(target >= 100,000 at N = 64 on one core)")
    return 0
