"""Runs of motion ticks handed to a batched environment, one call per run of equal tick length."""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from typing import Protocol

from forcelearn.emulators.physics.arm_motion import PoseKey


class TicksInOneCall(Protocol):
    """An environment's ``ticks`` (``BatchTickedEnvironment``'s)."""

    def ticks(self, keys: Sequence[PoseKey], dt_s: float, before: PoseKey) -> PoseKey:
        """``tick`` for each tool key, ``dt_s`` (s) each; returns the last key recorded."""
        ...


def ticks_by_length(environment: TicksInOneCall,
                    runs: Iterable[tuple[Sequence[PoseKey], float]], before: PoseKey) -> PoseKey:
    """``environment.ticks`` of each ``(keys, dt_s)`` in order; the last key recorded.

    The keys of consecutive runs of the same ``dt_s`` (s) go in one call; ``before``
    is the key recorded before the first.
    """
    recorded, keys, dt = before, list[PoseKey](), 0.0
    for run_keys, run_dt in runs:
        if run_dt != dt and keys:
            recorded = environment.ticks(keys, dt, recorded)
            keys = []
        dt = run_dt
        keys += run_keys
    if keys:
        recorded = environment.ticks(keys, dt, recorded)
    return recorded
