"""SAC (stable-baselines3) on ``forcelearn/Surface-v0``, scored by the same rule as the others.

Needs ``pip install 'forcelearn[baselines]'`` (stable-baselines3 and PyTorch).
Observations are rescaled to [-1, 1] (Gymnasium's ``RescaleObservation``);
the :class:`~forcelearn.baselines.runner.TrialRecorder` sits under it, so every
episode SAC plays, exploration included, is a trial of the record. Learning
stops by the same budget rule as the other methods (converged + 10 trials, or
``trials``).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import gymnasium
import numpy as np

from forcelearn.baselines.runner import TrialRecorder, should_stop
from forcelearn.errors import ForcelearnError


class BaselineUnavailable(ForcelearnError):
    """An optional baseline's package is not installed."""


@dataclass(frozen=True)
class SACParams:
    """SAC hyperparameters (SB3's defaults except where said)."""

    learning_starts: int = 100
    """Random-action steps before learning (5 trials; SB3's default is 100)."""
    learning_rate: float = 3e-4
    batch_size: int = 256
    gamma: float = 0.9
    """Discount; 0.9 (SB3: 0.99) as an episode is only 20 steps and r is per step."""
    net_arch: tuple[int, ...] = (64, 64)
    """Hidden layers of actor and critics (SB3: 256, 256; smaller is quicker on 2 cores)."""
    threads: int = 1
    """PyTorch's CPU threads (``torch.set_num_threads``): one, as a study runs one process a
    core; at this network size more threads do not pay for their hand-overs."""


def run_sac(
    env: gymnasium.Env[np.ndarray, np.ndarray],
    seed: int,
    trials: int,
    params: SACParams | None = None,
) -> tuple[TrialRecorder, Any]:
    """Train SAC on ``env`` until the budget rule stops it; return the recorder and the model."""
    try:
        from stable_baselines3 import SAC
        from stable_baselines3.common.callbacks import BaseCallback
    except ImportError as exc:
        raise BaselineUnavailable(
            "SAC needs stable-baselines3: pip install 'forcelearn[baselines]'"
        ) from exc
    p = params or SACParams()
    import torch

    torch.set_num_threads(p.threads)
    recorder = TrialRecorder(env, "sac")
    task: Any = recorder.unwrapped
    wrapped = gymnasium.wrappers.RescaleObservation(recorder, np.float64(-1.0), np.float64(1.0))

    class Budget(BaseCallback):  # type: ignore[misc,unused-ignore]  # Any without SB3 installed
        def _on_step(self) -> bool:
            return not should_stop(
                recorder.records, trials, task.task_steps_per_trial, task.task_desired_force_n
            )

    model = SAC(
        "MlpPolicy",
        wrapped,
        learning_rate=p.learning_rate,
        batch_size=p.batch_size,
        gamma=p.gamma,
        learning_starts=p.learning_starts,
        policy_kwargs={"net_arch": list(p.net_arch)},
        seed=seed,
        device="cpu",
        verbose=0,
    )
    model.learn(total_timesteps=trials * task.task_steps_per_trial, callback=Budget())
    return recorder, model
