"""What a foam remembers between reports: passes, relaxation, hysteresis branch, last slide.

The strip sponge (:class:`~forcelearn.emulators.physics.sponge.Sponge`) and a part's foam
(:class:`~forcelearn.emulators.physics.part_foam.PartFoam`) keep the same state, forget their
branch the same way when the tool leaves the foam, and checkpoint it under the same keys.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

Position = tuple[float, float, float]
"""A tool position (x, y, z), mm."""

State = dict[str, int | bool | float]
"""A checkpointed state: plain numbers by key."""


class FoamMemory:
    """The state one foam carries from report to report (lengths in mm)."""

    def __init__(self, passes: int = 0) -> None:
        self.passes = passes
        """Completed passes (contact, then free space)."""
        self._touched = False
        self.relaxing_mm = 0.0
        """The relaxing part q of the standard linear solid, mm."""
        self._foam_mm = 0.0
        self.hysteresis_state = 0.0
        """The Dahl state s in [-1, 1] (+1: pressing in, -1: easing off; 0 off the foam)."""
        self._hysteresis_foam_mm = 0.0
        """The foam depth the hysteresis state was last brought to, mm."""
        self.slide_direction: tuple[float, float, float] = (0.0, 0.0, 0.0)
        """Unit direction of the tool's last slide along the surface (zeros: none)."""
        self._last_position: tuple[float, float, float] | None = None
        """Where the tool was at the last report (hysteresis and friction only), mm."""

    def _forget_branch(self) -> None:
        """Off the foam: it forgets its branch, nothing holds its skin."""
        self.hysteresis_state = 0.0
        self._hysteresis_foam_mm = 0.0
        self.slide_direction = (0.0, 0.0, 0.0)

    def _arrive(self, position_mm: np.ndarray | Sequence[float], depth_mm: float
                ) -> tuple[Position, Position | None] | None:
        """Record a reported position; return (here, the last one), or None off the foam.

        Off the foam (``depth_mm`` <= 0) the branch is forgotten (:meth:`_forget_branch`).
        """
        here = (float(position_mm[0]), float(position_mm[1]), float(position_mm[2]))
        last, self._last_position = self._last_position, here
        if depth_mm <= 0.0:
            self._forget_branch()
            return None
        return here, last

    def _memory_state(self) -> State:
        """The remembered state as plain numbers (:meth:`_load_memory` restores it)."""
        state: State = {
            "passes": self.passes,
            "touched": self._touched,
            "relaxing_mm": self.relaxing_mm,
            "foam_mm": self._foam_mm,
            "hysteresis_state": self.hysteresis_state,
            "hysteresis_foam_mm": self._hysteresis_foam_mm,
            "has_last_position": self._last_position is not None,
        }
        for axis, value in zip("xyz", self.slide_direction, strict=True):
            state[f"slide_{axis}"] = value
        for axis, value in zip("xyz", self._last_position or (0.0, 0.0, 0.0), strict=True):
            state[f"last_{axis}_mm"] = value
        return state

    def _load_memory(self, state: State) -> None:
        """Restore :meth:`_memory_state` (keys it lacks take their fresh values)."""
        self.passes = int(state["passes"])
        self._touched = bool(state["touched"])
        self.relaxing_mm = float(state.get("relaxing_mm", 0.0))
        self._foam_mm = float(state.get("foam_mm", 0.0))
        self.hysteresis_state = float(state.get("hysteresis_state", 0.0))
        self._hysteresis_foam_mm = float(state.get("hysteresis_foam_mm", 0.0))
        x, y, z = (float(state.get(f"slide_{axis}", 0.0)) for axis in "xyz")
        self.slide_direction = (x, y, z)
        self._last_position = None
        if state.get("has_last_position", False):
            lx, ly, lz = (float(state[f"last_{axis}_mm"]) for axis in "xyz")
            self._last_position = (lx, ly, lz)
