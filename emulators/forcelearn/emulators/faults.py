"""The fault primitive every emulator's fault hook is built from.

A :class:`Fault` fires with a probability, at most ``limit`` times
(``Fault(1.0, limit=1)`` is "exactly the next one"); each emulator's own
fault config (the computer link's, EGM's...) names which of its events it
applies to; its injector (a :class:`FaultInjectorBase`) draws from a generator
seeded by the config, so a failing run can be replayed, and counts what fired.
"""

from __future__ import annotations

import threading
from collections import Counter
from dataclasses import dataclass
from typing import Generic, Protocol, TypeVar

import numpy as np


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


class SeededFaults(Protocol):
    """A fault config: its faults as :class:`Fault` attributes, and the generator's seed."""

    @property
    def seed(self) -> int:
        """Seed of the injector's ``numpy.random.Generator``."""


ConfigT = TypeVar("ConfigT", bound=SeededFaults)


class FaultInjectorBase(Generic[ConfigT]):
    """Decides, event by event, whether a fault of ``config`` fires; counts what fired.

    Thread-safe. A fault with probability 0 draws nothing, one with probability 1
    draws nothing either, so adding a certain fault leaves the others' draws as
    they were.
    """

    def __init__(self, config: ConfigT) -> None:
        self.config = config
        self._rng = np.random.default_rng(config.seed)
        self._lock = threading.Lock()
        self.fired: Counter[str] = Counter()

    def fires(self, name: str) -> bool:
        """True if fault ``name`` (an attribute of the config) fires now."""
        fault: Fault = getattr(self.config, name)
        if fault.probability == 0.0 or not self._armed():
            return False
        with self._lock:
            if fault.limit is not None and self.fired[name] >= fault.limit:
                return False
            if fault.probability < 1.0 and self._rng.random() >= fault.probability:
                return False
            self.fired[name] += 1
            return True

    def _armed(self) -> bool:
        """Whether faults may fire now at all (always, unless a subclass says otherwise)."""
        return True
