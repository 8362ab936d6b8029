"""What a learner over BOXES needs of a §5 surface env (Surface-v0 and SurfaceSim-v0 alike).

The SRV learner (:mod:`forcelearn.baselines.srv`) reads its input and maps its
action through the env's task spec and output map, whatever steps the cell.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from forcelearn.tasks.surface_map import OutputMapChoice
from forcelearn.tasks.surface_spec import SurfaceTaskSpec


class SurfaceLearnerAdapter:
    """Mixin: the learner's input, action and grid from ``task_spec`` and ``output_map``."""

    task_spec: SurfaceTaskSpec
    output_map: OutputMapChoice

    def learner_input(self, obs: np.ndarray) -> np.ndarray:
        """The SRV learner's input: distance travelled, mm."""
        return np.asarray(obs[:1], dtype=float)

    def learner_action(self, a: np.ndarray, x: np.ndarray) -> np.ndarray:
        """Map the learner's action a (action units) to this env's action in [-1, 1].

        The native output map: Y offset = scale · a, clipped to ± the half-range.
        """
        choice = self.output_map
        offset = np.clip(a * choice.scale_mm, -choice.max_offset_mm, choice.max_offset_mm)
        return offset / choice.max_offset_mm

    @property
    def grid(self) -> Any:
        """The BOXES partition of the native task (distance travelled)."""
        return self.task_spec.grid()
