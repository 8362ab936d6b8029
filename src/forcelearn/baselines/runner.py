"""Run any controller on a forcelearn environment, one trial per episode, with the project's rule.

Every method of the comparison (the paper's SRV learner and the baselines)
runs through the same Gymnasium environment and is scored by the same
:class:`TrialRecorder`, which turns each finished episode into a
:class:`~forcelearn.trainer.TrialRecord` with the trainer's formulas (steps =
completed steps, force RMS over every measured step, mean r, start force, cell
time). Convergence is :func:`~forcelearn.trainer.converged_trial` (10 complete
trials in a row, each with force RMS ≤ 5 % of the desired force).

**Budget** (:func:`should_stop`): a run stops once it has converged and run
``after`` (10) more trials past the convergence window, or at ``trials``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, Protocol, SupportsFloat

import gymnasium
import numpy as np

from forcelearn.trainer import CONVERGENCE_WINDOW, TrialRecord, converged_trial

AFTER_CONVERGED = 10
"""Trials run after the convergence window before a run stops."""


@dataclass
class TrialStats:
    """What the recorder keeps besides the records: per trial, the largest force met, N."""

    peak_force_n: list[float] = field(default_factory=list)


class TrialRecorder(gymnasium.Wrapper[np.ndarray, np.ndarray, np.ndarray, np.ndarray]):
    """Records one :class:`TrialRecord` per finished episode (any agent, SB3's included).

    Args:
        env: a forcelearn environment (or a wrapper of one).
        method: written in the records' ``phase`` field.
    """

    def __init__(self, env: gymnasium.Env[np.ndarray, np.ndarray], method: str):
        super().__init__(env)
        self.method = method
        self.records: list[TrialRecord] = []
        self.stats = TrialStats()
        self._rs: list[float] = []
        self._errors: list[float] = []
        self._forces: list[float] = []
        self._start_force_n = math.nan

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[np.ndarray, dict[str, Any]]:
        """Begin a trial."""
        obs, info = self.env.reset(seed=seed, options=options)
        self._rs, self._errors = [], []
        self._start_force_n = float(info.get("start_force_n", math.nan))
        self._forces = [self._start_force_n]
        return obs, info

    def step(
        self, action: np.ndarray
    ) -> tuple[np.ndarray, SupportsFloat, bool, bool, dict[str, Any]]:
        """One step; a finished episode becomes a record."""
        obs, reward, terminated, truncated, info = self.env.step(action)
        self._rs.append(float(info["r"]))
        self._errors.append(float(info["force_error_n"]))
        self._forces.append(float(info["force_n"]))
        if terminated or truncated:
            self.records.append(
                TrialRecord(
                    index=len(self.records),
                    phase=self.method,
                    steps=len(self._rs) - (1 if terminated else 0),
                    failed=bool(terminated),
                    mean_r=float(np.mean(self._rs)),
                    force_rms_n=float(np.sqrt(np.mean(np.square(self._errors)))),
                    start_force_n=self._start_force_n,
                    cell_time_s=float(info.get("trial_cell_time_s", math.nan)),
                )
            )
            finite = [f for f in self._forces if math.isfinite(f)]
            self.stats.peak_force_n.append(max(finite) if finite else math.nan)
        return obs, reward, terminated, truncated, info


def should_stop(
    records: list[TrialRecord],
    trials: int,
    steps_per_trial: int,
    desired_force_n: float,
    after: int = AFTER_CONVERGED,
) -> bool:
    """True once the budget is spent or the run converged and ran ``after`` trials past it."""
    if len(records) >= trials:
        return True
    start = converged_trial(records, steps_per_trial, desired_force_n)
    return start is not None and len(records) >= start + CONVERGENCE_WINDOW + after


class Controller(Protocol):
    """A method driven trial by trial (the SRV learner, force control, ILC, CMA-ES)."""

    name: str

    def begin(self, obs: np.ndarray, info: dict[str, Any]) -> None:
        """A trial starts at ``obs`` (``info["start_force_n"]``: the start force, N)."""
        ...

    def act(self, obs: np.ndarray) -> np.ndarray:
        """The env action in [-1, 1] for this step."""
        ...

    def observe(self, obs: np.ndarray, info: dict[str, Any]) -> None:
        """What followed the last action (``info["r"]``, ``info["force_n"]`` ...)."""
        ...

    def end(self, record: TrialRecord) -> None:
        """The trial ended (its record is final)."""
        ...


def run_controller(
    env: gymnasium.Env[np.ndarray, np.ndarray],
    controller: Controller,
    trials: int,
    seed: int,
    stop_early: bool = True,
) -> TrialRecorder:
    """Run trials until :func:`should_stop` (or ``trials`` if not ``stop_early``).

    The first reset is seeded (a fresh emulated cell); the later ones keep the
    cell, so the sponge wears on as it does under the native trainer.
    """
    recorder = env if isinstance(env, TrialRecorder) else TrialRecorder(env, controller.name)
    task = recorder.unwrapped
    steps_per_trial = int(task.task_steps_per_trial)  # type: ignore[attr-defined]
    desired = float(task.task_desired_force_n)  # type: ignore[attr-defined]
    for index in range(trials):
        obs, info = recorder.reset(seed=seed if index == 0 else None)
        controller.begin(obs, info)
        done = False
        while not done:
            obs, _, terminated, truncated, info = recorder.step(controller.act(obs))
            controller.observe(obs, info)
            done = terminated or truncated
        controller.end(recorder.records[-1])
        if stop_early and should_stop(recorder.records, trials, steps_per_trial, desired):
            break
    return recorder
