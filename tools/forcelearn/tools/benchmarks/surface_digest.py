"""A fixed-seed ``forcelearn/Surface-v0`` run's SHA-256: a speed change must leave it as it is.

``python -m forcelearn.tools.benchmarks.surface_digest`` resets the env with
seed 3, steps it with 150 zero actions then 150 uniform random ones (their own
generator, seed 3), resetting without a seed at every episode's end, and hashes
every observation (its bytes), reward (``float.hex``), the two flags and every
info item (``repr``), the resets' included. Two trees that print the same digest
ran the same episodes to the bit.
"""

from __future__ import annotations

import argparse
import hashlib
from typing import Any

import numpy as np

SEED = 3
ZERO_STEPS = 150
RANDOM_STEPS = 150


def _info_items(info: dict[str, Any]) -> list[tuple[str, str]]:
    return sorted((key, repr(value)) for key, value in info.items())


def digest(seed: int = SEED, zero_steps: int = ZERO_STEPS, random_steps: int = RANDOM_STEPS) -> str:
    """The SHA-256 (hex) of a run: ``zero_steps`` zero actions, then ``random_steps`` random."""
    import gymnasium

    import forcelearn.envs  # noqa: F401  (registers the ids)

    env = gymnasium.make("forcelearn/Surface-v0")
    sha = hashlib.sha256()

    def put(*parts: object) -> None:
        sha.update(repr(parts).encode())

    try:
        obs, info = env.reset(seed=seed)
        put("reset", np.asarray(obs).tobytes(), _info_items(info))
        rng = np.random.default_rng(seed)
        space = env.action_space
        if not isinstance(space, gymnasium.spaces.Box):  # pragma: no cover - Surface-v0's is
            raise TypeError(f"Surface-v0's action space is a Box, not {space}")
        shape, dtype = space.shape, space.dtype
        for i in range(zero_steps + random_steps):
            action = (np.zeros(shape, dtype=dtype) if i < zero_steps
                      else rng.uniform(-1.0, 1.0, shape).astype(dtype))
            obs, reward, terminated, truncated, info = env.step(action)
            put(np.asarray(obs).tobytes(), float(reward).hex(), terminated, truncated,
                _info_items(info))
            if terminated or truncated:
                obs, info = env.reset()
                put("reset", np.asarray(obs).tobytes(), _info_items(info))
    finally:
        env.close()
    return sha.hexdigest()


def main(argv: list[str] | None = None) -> int:
    """Print the digest."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0] if __doc__ else None)
    parser.add_argument("--seed", type=int, default=SEED)
    parser.add_argument("--zero-steps", type=int, default=ZERO_STEPS)
    parser.add_argument("--random-steps", type=int, default=RANDOM_STEPS)
    args = parser.parse_args(argv)
    print(digest(args.seed, args.zero_steps, args.random_steps))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
