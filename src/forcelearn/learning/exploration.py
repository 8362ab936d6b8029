"""The SRV unit's pieces around the Gaussian search: σ = s(r̂) and the output map y(a).

``s`` (paper Fig. 2) must be non-negative and monotonically increasing in the
predicted evaluation r̂ (smaller r is better, r > 1 is a failure). This project
uses a linear ramp between a floor and a ceiling::

    s(r̂) = σ_min + (σ_max − σ_min) · clip(r̂, 0, 1)

so a box predicted to fail searches widely (σ_max) and a box predicted to be
perfect still searches a little (σ_min > 0, which also keeps eq. (2)'s
division by σ defined). Actions are in *action units*; the output map scales
them to the device (joint degrees, millimetres, ...).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Protocol

import numpy as np


def sigma_of_prediction(r_hat: float, sigma_min: float, sigma_max: float) -> float:
    """Return σ = s(r̂), the search width in action units, for a predicted evaluation r̂."""
    clipped = 0.0 if r_hat < 0.0 else (1.0 if r_hat > 1.0 else r_hat)
    return sigma_min + (sigma_max - sigma_min) * clipped


class OutputMap(Protocol):
    """y: maps the SRV action ``a`` (action units) and the input ``x`` to the control output."""

    def __call__(self, a: np.ndarray, x: np.ndarray) -> np.ndarray:
        """Return the control output for action ``a`` taken at input ``x``."""
        ...


class IdentityOutput:
    """y(a) = a: the action is the command."""

    def __call__(self, a: np.ndarray, x: np.ndarray) -> np.ndarray:
        """Return ``a`` unchanged."""
        return a


@dataclass(frozen=True)
class AffineOutput:
    """y(a) = offset + scale · a, per output, optionally clipped to [low, high]."""

    scale: Sequence[float]
    offset: Sequence[float] = (0.0,)
    low: Sequence[float] | None = None
    high: Sequence[float] | None = None

    def __call__(self, a: np.ndarray, x: np.ndarray) -> np.ndarray:
        """Return the scaled, offset and clipped command."""
        scale = np.asarray(self.scale, dtype=float)
        y: np.ndarray = np.asarray(self.offset, dtype=float) + scale * a
        if self.low is not None or self.high is not None:
            y = np.clip(y, self.low, self.high)
        return y
