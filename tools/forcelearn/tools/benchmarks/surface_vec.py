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
    """Return env steps per wall second (all cells counted) over ``seconds`` of stepping."""
    return measure_rates(num_envs, seconds, seed)[0]


def measure_rates(num_envs: int, seconds: float, seed: int = 0) -> tuple[float, float]:
    """Env steps (all cells) per wall second and per CPU second of this process.

    On a shared machine the CPU figure is the one core's rate; the wall figure
    is lower by the share of the core other processes took.
    """
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
    start, cpu_start = time.perf_counter(), time.process_time()
    while (elapsed := time.perf_counter() - start) < seconds:
        for k in range(64):
            envs.step(actions[(steps + k) % 256])
        steps += 64
    cpu_s = time.process_time() - cpu_start
    return steps * num_envs / elapsed, steps * num_envs / cpu_s


def run(args: argparse.Namespace) -> int:
    """Print env steps/s."""
    wall, cpu = measure_rates(args.num_envs, args.seconds)
    print(f"forcelearn/SurfaceVec-v0, N = {args.num_envs}: {wall:,.0f} env steps/s of wall time, "
          f"{cpu:,.0f} per CPU second (target >= 100,000 at N = 64 on one core)")
    return 0
