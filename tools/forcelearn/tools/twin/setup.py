"""The base values and reading geometry a run's config gives the twin's fit."""

from __future__ import annotations

import dataclasses

from forcelearn.site.config import CellConfig
from forcelearn.tools.twin.forward import Reading
from forcelearn.tools.twin.params import ARM


def base_sponge(config: CellConfig) -> dict[str, float]:
    """The config's sponge, every field as a float (the fit's start and fixed values)."""
    return {k: float(v) for k, v in dataclasses.asdict(config.emulator.sponge).items()}


def base_arm(config: CellConfig) -> dict[str, float]:
    """The config's arm timing parameters."""
    return {p.name: float(getattr(config.emulator.arm, p.name)) for p in ARM}


def reading_of(config: CellConfig) -> Reading:
    """How the run read the normal force: the task's tool orientation, the filter's axis."""
    return Reading.of(config.task.orientation, config.filter.axis, config.filter.sign)
