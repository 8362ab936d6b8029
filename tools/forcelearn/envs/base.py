"""One Gymnasium adapter over any :class:`~forcelearn.trainer.EpisodicTask`.

The subclasses (``ContourEnv``, ``SurfaceEnv``) say how a task is built, how an
action in [-1, 1] becomes the task's command and how the task's state becomes
an observation. Everything else is shared and follows the trainer's S3-S9
loop exactly: one ``step`` is one control step of the task, a failed step
ends the episode as *terminated*, the end of the path as *truncated*, and the
reward is −r (r the paper's evaluation, smaller is better).

``info`` of every ``step`` holds what the trainer's step log holds:

==================  ==========================================================
``r``               the evaluation (dimensionless; > 1 is a failure)
``force_n``         measured normal force after the step, N
``force_error_n``   measured minus desired force, N
``failed``          the step failed (same as ``terminated``)
``step``            steps done in this episode (1 after the first)
``trial_cell_time_s``  the cell's clock since the episode's reset began, s
                    (only on a cell with a clock, not in a pure simulation)
``command``         the task command the action became (task units)
...                 the task's own extras (``y_cmd_mm``, ``theta1_deg`` ...)
==================  ==========================================================

``reset`` returns ``info = {"start_force_n": ...}``: the force measured at the
start pose, with the subclass's own extras (:meth:`TaskEnv._reset_info`).
"""

from __future__ import annotations

import math
from typing import Any, Protocol

import gymnasium
import numpy as np
from gymnasium import spaces
from gymnasium.error import ResetNeeded

from forcelearn.trainer import EpisodicTask, StepOutcome

RENDER_SIZE_PX = (320, 240)
"""Width and height of the ``rgb_array`` frame, pixels."""


class TaskEnv(gymnasium.Env[np.ndarray, np.ndarray]):
    """Base of the forcelearn environments; not registered itself (see the subclasses)."""

    # Not a ClassVar: gymnasium.Env declares ``metadata`` an instance attribute.
    metadata = {"render_modes": ["rgb_array"], "render_fps": 4}  # noqa: RUF012

    action_space: spaces.Box
    observation_space: spaces.Box
    task_steps_per_trial: int
    """Steps of a complete episode (the path's end)."""
    task_desired_force_n: float
    """The desired normal force, N."""

    def __init__(self, render_mode: str | None = None):
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise ValueError(
                f"render_mode={render_mode!r}: one of {self.metadata['render_modes']} or None"
            )
        self.render_mode = render_mode
        self.task: EpisodicTask | None = None
        self._x: np.ndarray = np.zeros(0)
        self._steps = 0
        self._done = True
        self._forces: list[float] = []

    # -- hooks of the subclasses -------------------------------------------------------------
    def _open_task(self, seed: int | None) -> EpisodicTask:
        """Build (or rebuild, for a new seed) the task and its cell."""
        raise NotImplementedError

    def _needs_new_task(self, seed: int | None) -> bool:
        """True when ``reset(seed=...)`` must rebuild the task."""
        return self.task is None or seed is not None

    def _command(self, action: np.ndarray) -> np.ndarray:
        """Map an action in [-1, 1] to the task's command (task units)."""
        raise NotImplementedError

    def _observation(self, x: np.ndarray, force_n: float) -> np.ndarray:
        """The observation for the task input ``x`` and the last measured force (N)."""
        raise NotImplementedError

    def _reset_info(self) -> dict[str, Any]:
        """Extras of ``reset``'s info (none by default)."""
        return {}

    # -- the Gymnasium API ---------------------------------------------------------------------
    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[np.ndarray, dict[str, Any]]:
        """Return to the start pose (rebuilding the cell when a seed is given)."""
        super().reset(seed=seed)
        if self._needs_new_task(seed):
            self.close_task()
            self.task = self._open_task(seed)
        task = self._require_task()
        self._x = np.asarray(task.reset(), dtype=float)
        self._steps = 0
        self._done = False
        self._forces = [float(task.start_force_n)]
        obs = self._observation(self._x, float(task.start_force_n))
        return obs, {"start_force_n": float(task.start_force_n), **self._reset_info()}

    def step(self, action: np.ndarray) -> tuple[np.ndarray, float, bool, bool, dict[str, Any]]:
        """Apply one control step; see the class docstring for the returned values."""
        if self._done:
            raise ResetNeeded("the episode has ended (or never began): call reset() first")
        task = self._require_task()
        u = np.asarray(action, dtype=float).reshape(self.action_space.shape)
        if not np.all(np.isfinite(u)):
            raise ValueError(f"action must be finite, got {action!r}")
        command = self._command(np.clip(u, -1.0, 1.0))
        outcome: StepOutcome = task.step(command)
        self._steps += 1
        self._x = np.asarray(outcome.x, dtype=float)
        self._forces.append(float(outcome.force_n))
        terminated = bool(outcome.failed)
        truncated = not terminated and self._steps >= task.steps_per_trial
        self._done = terminated or truncated
        info: dict[str, Any] = {
            "r": float(outcome.r),
            "force_n": float(outcome.force_n),
            "force_error_n": float(outcome.force_error_n),
            "failed": terminated,
            "step": self._steps,
            "command": command.copy(),
            **outcome.extras,
        }
        if hasattr(task, "trial_cell_time_s"):  # tasks on a cell with a clock
            info["trial_cell_time_s"] = float(task.trial_cell_time_s)
        obs = self._observation(self._x, float(outcome.force_n))
        return obs, -float(outcome.r), terminated, truncated, info

    def render(self) -> np.ndarray | None:
        """With ``render_mode="rgb_array"``: the episode's force trace as an RGB array."""
        if self.render_mode != "rgb_array":
            return None
        task = self._require_task()
        return force_trace_rgb(self._forces, task.desired_force_n, task.steps_per_trial)

    def close_task(self) -> None:
        """Release the task's cell (subclasses stop the robot here)."""
        self.task = None

    def close(self) -> None:
        """Stop the robot and release the cell; safe to call twice."""
        self.close_task()
        self._done = True
        super().close()

    def _require_task(self) -> EpisodicTask:
        if self.task is None:
            raise ResetNeeded("the environment has no cell yet: call reset() first")
        return self.task


def box(low: list[float], high: list[float]) -> spaces.Box:
    """A float64 Box from per-component bounds."""
    return spaces.Box(np.array(low, dtype=float), np.array(high, dtype=float), dtype=np.float64)


class _RgbaCanvas(Protocol):
    """What is drawn on here of matplotlib's Agg canvas (whose methods are not annotated)."""

    def draw(self) -> None: ...

    def buffer_rgba(self) -> memoryview: ...


def force_trace_rgb(forces: list[float], desired_n: float, steps: int) -> np.ndarray:
    """Draw the force per step (start force at step 0) against the desired force; RGB uint8."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    width, height = RENDER_SIZE_PX
    fig = Figure(figsize=(width / 80, height / 80), dpi=80)
    canvas: _RgbaCanvas = FigureCanvasAgg(fig)
    ax = fig.add_subplot()
    ax.axhline(desired_n, color="tab:green", lw=1, label="desired")
    ax.plot(range(len(forces)), forces, "o-", color="tab:blue", ms=3, label="measured")
    ax.set_xlim(0, steps)
    top = max([2 * desired_n, *[f for f in forces if math.isfinite(f)]])
    ax.set_ylim(min(0.0, *[f for f in forces if math.isfinite(f)]), 1.05 * top)
    ax.set_xlabel("step")
    ax.set_ylabel("force (N)")
    ax.legend(loc="lower right", fontsize=6)
    fig.tight_layout()
    canvas.draw()
    rgba = np.asarray(canvas.buffer_rgba())
    return np.ascontiguousarray(rgba[:, :, :3])
