"""The base values and reading geometry a run's config gives the twin's fit."""

from __future__ import annotations

import dataclasses
import math

from forcelearn.emulators.physics.arm import ArmConfig
from forcelearn.emulators.physics.sponge import SpongeParams
from forcelearn.records import TrialRecords
from forcelearn.site.config import CellConfig
from forcelearn.tools.twin.arrays import to_arrays
from forcelearn.tools.twin.forward import Reading, mean_sample_period_s
from forcelearn.tools.twin.params import ARM

GEOMETRY = ("z_top_mm", "z_bottom_mm", "thickness_mm", "backing_n_per_mm")
"""Sponge keys the fit does not touch: the strip's ends, its thickness and backing (a site
measures them with a ruler; the run's ``[emulator.sponge]`` gives them when it has them)."""


def base_sponge(config: CellConfig) -> dict[str, float]:
    """The fit's start and held values: the emulator's defaults, the run's geometry.

    Only :data:`GEOMETRY` is read from the run's config: its other ``[emulator.sponge]``
    keys (an emulated run's hidden truth) never reach the fit.
    """
    base = {k: float(v) for k, v in dataclasses.asdict(SpongeParams()).items()}
    run = dataclasses.asdict(config.emulator.sponge)
    base.update({k: float(run[k]) for k in GEOMETRY})
    return base


def base_arm(config: CellConfig | None = None) -> dict[str, float]:
    """The arm's timing parameters of ``config`` (default: the emulator's defaults)."""
    arm = config.emulator.arm if config is not None else ArmConfig()
    return {p.name: float(getattr(arm, p.name)) for p in ARM}


def reading_of(config: CellConfig) -> Reading:
    """How the run read the normal force: the task's tool orientation, the filter's axis."""
    return Reading.of(config.task.orientation, config.filter.axis, config.filter.sign)


def configured_colour(config: CellConfig, records: list[TrialRecords]) -> float | None:
    """AR(1) coefficient per burst sample of the noise the run's sensor settings give.

    The JR3 adapter's first-order low-pass at ``[sensor] cutoff_hz`` colours the
    noise: ``exp(-2 pi cutoff dt)`` at the bursts' sample period; the Net F/T's
    is white (0). None when the bursts have no sample period.
    """
    cutoff = float(getattr(config.sensor, "cutoff_hz", 0.0) or 0.0)
    emulate_filter = getattr(config.sensor_device.model(config.emulator), "emulate_filter", True)
    if cutoff <= 0 or not emulate_filter:
        return 0.0
    period = mean_sample_period_s(to_arrays(records))
    if not math.isfinite(period):
        return None
    return math.exp(-2 * math.pi * cutoff * period)
