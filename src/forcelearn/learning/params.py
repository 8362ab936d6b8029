"""Hyperparameters of the SRV learner, with the paper's values as defaults.

The defaults are those of the paper's §4 simulation (two-link arm, 2-D BOXES);
§5's experiment uses γ = 0.8 and a specialized α = 1, which its task sets.
Fields marked *not in the paper* are this project's choices; docs/learner.md
gives the reasons.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, fields
from typing import Any

from forcelearn.errors import ConfigError
from forcelearn.learning.phase import Phase


@dataclass(frozen=True)
class SRVParams:
    """Learning rates, neighbourhood and exploration of the SRV-over-BOXES learner."""

    alpha_generalized: float = 0.5
    """α of eqs. (2)-(3) in the generalized phase (§4: 0.5)."""
    beta_generalized: float = 0.5
    """β of eq. (1) in the generalized phase (§4: 0.5)."""
    alpha_specialized: float = 0.1
    """α of eq. (2) in the specialized phase (§4: 0.1)."""
    beta_specialized: float = 0.5
    """β of eq. (1) in the specialized phase (§4: 0.5)."""
    gamma: float = 0.9
    """γ, decay per box of distance in eq. (3), 0 < γ < 1 (§4: 0.9)."""
    extent: tuple[int, ...] = (5, 5)
    """d_i, neighbourhood extent per input dimension in boxes (§4: d1 = d2 = 5)."""
    success_trials: int = 10
    """N, the global criterion: consecutive successful trials to end the generalized phase."""
    sigma_min: float = 0.01
    """s(r̂ <= 0): exploration floor in action units (not in the paper)."""
    sigma_max: float = 0.5
    """s(r̂ >= 1): exploration at a failing prediction, action units (not in the paper)."""
    initial_prediction: float = 0.5
    """V at S1: r̂ of an untried box, half the failure threshold (not in the paper)."""
    initial_mean: float = 0.0
    """W at S1: μ of an untried box, action units (not in the paper)."""
    generalized_phase: bool = True
    """False skips the generalized phase (specialized-only ablation)."""

    def __post_init__(self) -> None:
        for name in (
            "alpha_generalized",
            "beta_generalized",
            "alpha_specialized",
            "beta_specialized",
        ):
            value = getattr(self, name)
            if not (math.isfinite(value) and value >= 0.0):
                raise ConfigError(f"{name} must be a finite number >= 0, got {value!r}")
        if not 0.0 < self.gamma < 1.0:
            raise ConfigError(f"gamma must lie in (0, 1), got {self.gamma!r}")
        object.__setattr__(self, "extent", tuple(int(d) for d in self.extent))
        if any(d < 0 for d in self.extent):
            raise ConfigError(f"extent must hold integers >= 0, got {self.extent!r}")
        if self.success_trials < 1:
            raise ConfigError(f"success_trials must be >= 1, got {self.success_trials!r}")
        if not 0.0 < self.sigma_min <= self.sigma_max:
            raise ConfigError(
                f"need 0 < sigma_min <= sigma_max, got {self.sigma_min!r}, {self.sigma_max!r}"
            )

    def alpha(self, phase: Phase) -> float:
        """α in force during ``phase``."""
        return self.alpha_generalized if phase is Phase.GENERALIZED else self.alpha_specialized

    def beta(self, phase: Phase) -> float:
        """β in force during ``phase``."""
        return self.beta_generalized if phase is Phase.GENERALIZED else self.beta_specialized

    def to_dict(self) -> dict[str, Any]:
        """Return the parameters as plain JSON-able values."""
        values = asdict(self)
        values["extent"] = list(self.extent)
        return values

    @classmethod
    def from_dict(cls, values: dict[str, Any]) -> SRVParams:
        """Build from a mapping; unknown keys are an error that names them."""
        known = {f.name for f in fields(cls)}
        unknown = sorted(set(values) - known)
        if unknown:
            raise ConfigError(f"unknown learner parameter(s) {unknown}; known: {sorted(known)}")
        values = dict(values)
        if "extent" in values:
            values["extent"] = tuple(values["extent"])
        return cls(**values)
