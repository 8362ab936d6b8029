"""A fake cell over the emulator's foam law (hysteresis included), for the task tests."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from forcelearn.devices import Pose
from forcelearn.emulators.physics.sponge import Sponge, SpongeParams

SUB_STEP_MM = 0.1
"""The fake robot reports its pose to the foam every this much of a move, mm."""


def foam(loss: float, depth_mm: float = 0.5) -> Sponge:
    """The emulator's foam law, elastic apart from its hysteresis (no relaxation, no wear)."""
    return Sponge(SpongeParams(hysteresis_loss=loss, hysteresis_depth_mm=depth_mm,
                               relaxation_ratio=0.0, softening=0.0, set_mm=0.0))


@dataclass
class _Filter:
    force_n: float = 0.0


@dataclass
class FoamCell:
    """A robot that moves exactly, reporting its pose to the emulator's foam as it goes."""

    foam: Sponge
    noise_n: float = 0.0
    stage: tuple[str, int] = ("move", 0)
    time_s: float = 0.0
    force_filter: _Filter = field(default_factory=_Filter)
    rng: np.random.Generator = field(default_factory=lambda: np.random.default_rng(0))
    _pose: Pose = field(default_factory=lambda: Pose(900.0, 15.0, 0.0))

    @property
    def pose(self) -> Pose:
        """Where the robot is."""
        return self._pose

    def sync(self) -> Pose:
        """Nothing to read."""
        return self._pose

    def move_in_steps(self, target: Pose, max_step_mm: float, guard_force: bool = False) -> int:
        """Move in a straight line, telling the foam every ``SUB_STEP_MM`` (in contact)."""
        start, end = self._pose.position_mm, target.position_mm
        touching = any(self.foam.contact_force_world_n(p)[1] > 0 for p in (start, end))
        length = float(np.linalg.norm(end - start))
        ticks = max(1, int(np.ceil(length / SUB_STEP_MM))) if touching else 1
        for i in range(1, ticks + 1):
            self.foam.observe_pose(start + (end - start) * i / ticks)
        self._pose = target
        self.force_filter.force_n = self.measure_force_n()
        return 1

    def tare(self, max_reading_n: float) -> bool:
        """Nothing to zero."""
        return True

    def reset_filter(self) -> None:
        """Nothing filtered."""

    def measure_force_n(self, samples: int | None = None) -> float:
        """The foam's normal force (+Y) where the robot is, with the sensor's noise."""
        force = float(self.foam.contact_force_world_n(self._pose.position_mm)[1])
        return force + (self.noise_n * float(self.rng.standard_normal()) if self.noise_n else 0.0)
