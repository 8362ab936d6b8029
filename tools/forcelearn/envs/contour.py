"""``forcelearn/Contour-v0``: the paper's §4 contour task (two-link arm, circular surface).

Pure simulation, fast (thousands of steps per second).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from forcelearn.envs.base import TaskEnv, box
from forcelearn.tasks.contour import ContourTask, ContourTaskSpec

MAX_OBS_FORCE_N = 20.0
"""Upper bound of the force observation, N (any force above 3 N has already failed)."""


class ContourEnv(TaskEnv):
    """Paper §4: a two-link arm tracks 1 N along a circular surface at 1 cm per step.

    ## Description
    A planar arm (links 1 m and 0.8 m) under ideal joint-position control
    presses on a compliant disc (100 N/m). Each step commands both joint angles;
    the aim is 1 N of normal force while the tip advances 1 cm along the
    surface. 45 steps make the path. Physics:
    ``forcelearn.emulators.physics.two_link_arm``; task: ``forcelearn.tasks.contour``.

    ## Action space: ``Box(-1, 1, (2,), float64)``
    | index | meaning | unit after scaling |
    |---|---|---|
    | 0 | increment of θ1 over the measured θ1 | ± ``max_step_deg`` (5°) |
    | 1 | increment of θ2 over the measured θ2 | ± ``max_step_deg`` (5°) |

    Actions outside [-1, 1] are clipped.

    ## Observation space: ``Box(float64, (3,))``
    | index | meaning | unit | bounds |
    |---|---|---|---|
    | 0 | measured θ1 | deg | [-180, 180] |
    | 1 | measured θ2 | deg | [-180, 180] |
    | 2 | normal force | N | [0, 20] (clipped) |

    ## Reward
    −r with eq. (4): r = |force − 1 N| / 2 N + |velocity − 1 cm| / 2 cm.

    ## Start state
    θ = (45°, −45°), force 0.7212 N; no randomness (the seed only seeds
    ``np_random`` for the agent's use).

    ## Episode end
    * terminated: r > 1 or the joints leave the partitioned ranges
      (θ1 ∈ [30°, 60°], θ2 ∈ [−75°, −15°]), the paper's failure;
    * truncated: 45 steps done without failure (the path's end).

    ## Arguments
    ``spec`` (:class:`ContourTaskSpec`), ``geometry`` (``ContourGeometry``),
    ``render_mode`` (``None`` or ``"rgb_array"``: the force trace of the episode).
    """

    def __init__(
        self,
        spec: ContourTaskSpec | None = None,
        geometry: Any | None = None,
        render_mode: str | None = None,
    ):
        super().__init__(render_mode)
        self.task_spec = spec or ContourTaskSpec()
        self.geometry = geometry
        self.task_steps_per_trial = self.task_spec.steps_per_trial
        self.task_desired_force_n = self.task_spec.desired_force_n
        self.action_space = box([-1.0, -1.0], [1.0, 1.0])
        self.observation_space = box([-180.0, -180.0, 0.0], [180.0, 180.0, MAX_OBS_FORCE_N])

    def _open_task(self, seed: int | None) -> ContourTask:
        # The physics lives in the emulators folder; imported here so that the
        # core package does not import it at module level (docs/architecture.md).
        from forcelearn.emulators.physics.two_link_arm import (
            ContourGeometry,
            TwoLinkContourCell,
        )

        geometry = self.geometry or ContourGeometry()
        return ContourTask(TwoLinkContourCell(geometry), self.task_spec)

    def _command(self, action: np.ndarray) -> np.ndarray:
        return self._x + action * self.task_spec.max_step_deg

    def _observation(self, x: np.ndarray, force_n: float) -> np.ndarray:
        obs = np.array([x[0], x[1], force_n], dtype=float)
        clipped: np.ndarray = np.clip(obs, self.observation_space.low, self.observation_space.high)
        return clipped

    # -- what a learner over BOXES needs (forcelearn.baselines.srv) --------------------------
    @property
    def grid(self) -> Any:
        """The BOXES partition of the native task, (θ1, θ2) in degrees."""
        return self.task_spec.grid()

    def learner_input(self, obs: np.ndarray) -> np.ndarray:
        """The SRV learner's input (θ1, θ2) in degrees, from an observation."""
        return np.asarray(obs[:2], dtype=float)

    def learner_action(self, a: np.ndarray, x: np.ndarray) -> np.ndarray:
        """Map the learner's action a (action units) to this env's action in [-1, 1].

        The same output map as the native task: increment a · 0.4° clipped to ±5°.
        """
        increment = np.clip(
            a * self.task_spec.output_scale_deg,
            -self.task_spec.max_step_deg,
            self.task_spec.max_step_deg,
        )
        return increment / self.task_spec.max_step_deg
