"""SRV units over a BOXES memory, learning in a generalized then a specialized phase.

One stochastic real-valued unit per box (paper §2, Fig. 2): ``W[box]`` holds the
mean action μ (one value per output), ``V[box]`` the predicted evaluation r̂.
With the one-hot box input X of BOXES, the paper's rules read:

* (S3) r̂ = V[box];  (S4) σ = s(r̂), a ~ N(μ, σ) per output, y = y(a, x)
* eq. (1), input box:            ΔV = β (r − r̂)
* eq. (2), input box:            ΔW = α (r̂ − r) (a − μ) / σ
* eq. (3), generalized phase, every other box within the extents d:
                                 ΔW = γ^(Σ|d̂_i|) α (r̂ − r) (a − μ)

r is an evaluation where smaller is better: a step that went better than
predicted (r < r̂) pulls μ towards a, a worse one pushes it away. Both rules use
the r̂, μ and σ of the moment the action was taken; α and β are those of the
phase in force. The neighbourhood update is one numpy slice operation: no
Python loop over boxes.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from forcelearn.errors import ConfigError
from forcelearn.learning.boxes import BoxGrid, InputVector, neighbourhood_kernel
from forcelearn.learning.exploration import IdentityOutput, OutputMap, sigma_of_prediction
from forcelearn.learning.params import SRVParams
from forcelearn.learning.phase import Phase, PhaseSchedule


@dataclass(frozen=True)
class Action:
    """What the learner did at one step, kept until the evaluation arrives."""

    box: tuple[int, ...]
    """The input box."""
    prediction: float
    """r̂, the box's predicted evaluation when acting."""
    sigma: float
    """σ = s(r̂), action units."""
    mean: np.ndarray
    """μ per output, action units."""
    action: np.ndarray
    """a ~ N(μ, σ) per output, action units."""
    output: np.ndarray
    """y(a, x), the control output in device units."""


def prediction_change(r_hat: float, r: float, beta: float) -> float:
    """Eq. (1): ΔV of the input box."""
    return beta * (r - r_hat)


def input_box_change(
    r_hat: float, r: float, a: np.ndarray, mu: np.ndarray, sigma: float, alpha: float
) -> np.ndarray:
    """Eq. (2): ΔW of the input box, per output."""
    change: np.ndarray = alpha * (r_hat - r) * (a - mu) / sigma
    return change


def neighbour_change(
    weight: np.ndarray | float, r_hat: float, r: float, a: np.ndarray, mu: np.ndarray, alpha: float
) -> np.ndarray:
    """Eq. (3): ΔW of a neighbour whose weight is γ^(Σ|d̂_i|) (σ removed)."""
    change: np.ndarray = np.multiply.outer(weight, alpha * (r_hat - r) * (a - mu))
    return change


class SRVLearner:
    """An SRV unit per box of ``grid``, with ``n_outputs`` action components each.

    Args:
        grid: the BOXES partition of the input.
        n_outputs: number of action components per box (e.g. two joint commands).
        params: learning rates, neighbourhood and exploration.
        rng: a ``numpy.random.Generator`` or a seed; all randomness comes from it.
        output: the output map y(a, x); identity by default.
    """

    def __init__(
        self,
        grid: BoxGrid,
        n_outputs: int = 1,
        params: SRVParams | None = None,
        rng: np.random.Generator | int | None = None,
        output: OutputMap | None = None,
    ):
        self.params = params or SRVParams()
        if len(self.params.extent) != grid.ndim:
            raise ConfigError(
                f"extent {self.params.extent} has {len(self.params.extent)} entries; "
                f"the grid has {grid.ndim} dimensions: give one extent d_i per dimension"
            )
        if n_outputs < 1:
            raise ConfigError(f"n_outputs must be >= 1, got {n_outputs}")
        self.grid = grid
        self.n_outputs = int(n_outputs)
        self.rng = rng if isinstance(rng, np.random.Generator) else np.random.default_rng(rng)
        self.output: OutputMap = output or IdentityOutput()
        self.weights = np.full((*grid.shape, self.n_outputs), self.params.initial_mean, float)
        self.predictions = np.full(grid.shape, self.params.initial_prediction, float)
        self.schedule = PhaseSchedule(
            success_trials=self.params.success_trials,
            phase=Phase.GENERALIZED if self.params.generalized_phase else Phase.SPECIALIZED,
        )
        kernel = neighbourhood_kernel(self.params.extent, self.params.gamma)
        kernel[tuple(self.params.extent)] = 0.0  # the input box follows eq. (2) instead
        self._kernel = kernel

    @property
    def phase(self) -> Phase:
        """The learning phase in force."""
        return self.schedule.phase

    def act(self, x: InputVector, explore: bool = True) -> Action:
        """Steps S3-S4: pick the box of ``x``, draw a ~ N(μ, σ), map it to y.

        With ``explore=False`` the action is the mean μ (for showing a learned policy).
        """
        box = self.grid.index(x)
        r_hat = float(self.predictions[box])
        sigma = sigma_of_prediction(r_hat, self.params.sigma_min, self.params.sigma_max)
        mu = self.weights[box].copy()
        a = mu + sigma * self.rng.standard_normal(self.n_outputs) if explore else mu.copy()
        y = np.asarray(self.output(a, np.asarray(x, dtype=float)), dtype=float)
        return Action(box, r_hat, sigma, mu, a, y)

    def learn(self, step: Action, r: float) -> None:
        """Steps S7-S8: update V by eq. (1) and W by eq. (2), plus eq. (3) if generalized."""
        if not np.isfinite(r):
            raise ValueError(f"evaluation r must be finite, got {r!r}")
        phase = self.schedule.phase
        alpha = self.params.alpha(phase)
        r_hat = step.prediction
        self.predictions[step.box] += prediction_change(r_hat, r, self.params.beta(phase))
        if phase is Phase.GENERALIZED:
            grid_slices, kernel_slices = self.grid.neighbourhood(step.box, self.params.extent)
            self.weights[grid_slices] += neighbour_change(
                self._kernel[kernel_slices], r_hat, r, step.action, step.mean, alpha
            )
        self.weights[step.box] += input_box_change(
            r_hat, r, step.action, step.mean, step.sigma, alpha
        )

    def end_trial(self, success: bool) -> bool:
        """Record a finished trial for the global criterion; True if the phase switched now."""
        return self.schedule.end_trial(success)
