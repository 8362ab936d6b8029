"""The base values and reading geometry a run's config gives the twin's fit."""

from __future__ import annotations

import dataclasses
import math

from forcelearn.records import TrialRecords
from forcelearn.site.config import CellConfig
from forcelearn.tools.twin.arrays import to_arrays
from forcelearn.tools.twin.forward import Reading, mean_sample_period_s
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


def configured_colour(config: CellConfig, records: list[TrialRecords]) -> float | None:
    """AR(1) coefficient per burst sample of the noise the run's sensor settings give.

    The JR3 adapter's first-order low-pass at ``[sensor] cutoff_hz`` colours the
    noise: ``exp(-2 pi cutoff dt)`` at the bursts' sample period; the Net F/T's
    is white (0). None when the bursts have no sample period.
    """
    if config.sensor_kind == "netft":
        return 0.0
    cutoff = float(getattr(config.sensor, "cutoff_hz", 0.0) or 0.0)
    if cutoff <= 0 or not config.emulator.sensor.emulate_filter:
        return 0.0
    period = mean_sample_period_s(to_arrays(records))
    if not math.isfinite(period):
        return None
    return math.exp(-2 * math.pi * cutoff * period)
