"""Client-side limits of every robot driver: the workspace box, the step and the speed.

A robot kind's driver checks a command against :class:`Limits` before it
leaves the PC; the cell config (:mod:`forcelearn.site.config`) builds them
from ``[safety]``. No transport here: the computer link, EGM and any new
robot kind share it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from forcelearn.errors import ConfigError


@dataclass(frozen=True)
class Limits:
    """Limits checked by the driver before a command leaves the PC (mm, mm/s).

    The controller may not enforce them; a command outside them raises
    ``SafetyStop`` and no byte is sent.
    """

    workspace_min_mm: tuple[float, float, float] = (300.0, -800.0, -200.0)
    """Lower corner of the allowed box of tool positions, base frame."""
    workspace_max_mm: tuple[float, float, float] = (1500.0, 800.0, 1400.0)
    """Upper corner of the allowed box of tool positions, base frame."""
    max_step_mm: float = 10.0
    """Largest distance between one commanded position and the next."""
    max_speed_mm_s: float = 250.0
    """Largest speed SET_SPEED may request (250 mm/s: ISO 10218 reduced speed)."""

    def __post_init__(self) -> None:
        for axis in range(3):
            if not self.workspace_min_mm[axis] < self.workspace_max_mm[axis]:
                raise ConfigError(
                    f"limits.workspace_min_mm[{axis}] must be below limits.workspace_max_mm[{axis}]"
                )
        for name in ("max_step_mm", "max_speed_mm_s"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0):
                raise ConfigError(f"limits.{name} must be a positive number, got {value!r}")
