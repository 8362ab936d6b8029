"""The fault primitive every emulator's fault hook is built from.

A :class:`Fault` fires with a probability, at most ``limit`` times
(``Fault(1.0, limit=1)`` is "exactly the next one"); each emulator's own
fault config (the computer link's, EGM's...) names which of its events it
applies to and draws from its seeded generator.
"""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class Fault:
    """Fire with ``probability`` (0..1), at most ``limit`` times (None: no limit)."""

    probability: float = 0.0
    limit: int | None = None

    def __post_init__(self) -> None:
        if not 0.0 <= self.probability <= 1.0:
            raise ValueError(f"fault probability must be in 0..1, got {self.probability}")
        if self.limit is not None and self.limit < 0:
            raise ValueError(f"fault limit must be >= 0, got {self.limit}")
