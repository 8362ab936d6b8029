"""A jackknife refit never ends above the cost it started from.

The refits are Gauss-Newton steps from the member's solution on the bursts a mask keeps.
Where the member fits loose parameters (a wear's time constant the records do not pin), a
full step along their nearly flat directions leaves the linear model's reach: on this run
every block's three full steps ended 1.2-6 times above its starting cost, and the spread
they gave was no uncertainty of the cell's.
"""

from __future__ import annotations

import numpy as np
import pytest

from forcelearn.emulators.physics.sponge import SpongeParams
from forcelearn.tools.twin import problem as problem_module
from forcelearn.tools.twin.arrays import to_arrays
from forcelearn.tools.twin.forward import Reading
from forcelearn.tools.twin.params import NONLINEAR_MEMBER
from forcelearn.tools.twin.problem import Problem, half_square
from forcelearn.tools.twin.simulate import DOWN, SimulatedRun, noise_only_sensor, simulate_run

READING = Reading.of(DOWN, 1, -1.0)
ARM = {"start_delay_s": 0.05, "accel_mm_s2": 1000.0, "default_speed_mm_s": 100.0,
       "lag_s": 0.03}
TRUTH = SpongeParams(stiffening_exponent=1.5, relaxation_ratio=0.05, softening=0.2,
                     softening_passes=300.0, set_mm=0.3, set_passes=200.0)
"""A stiffening foam that wears slowly: eight trials leave its wear's time constants loose."""


@pytest.fixture(scope="module")
def fitted() -> tuple[Problem, list[str], dict[str, float], list[np.ndarray]]:
    """The nonlinear member fitted to a noisy 8-trial run, and four block masks."""
    records = simulate_run(SimulatedRun(trials=8, steps=10, burst_samples=5, sponge=TRUTH,
                                        sensor=noise_only_sensor(0.1)), seed=4)
    data = to_arrays(records)
    names = [n for n in NONLINEAR_MEMBER.free if n not in dict(NONLINEAR_MEMBER.fixed)]
    start = {k: float(v) for k, v in SpongeParams().__dict__.items()}
    problem = Problem(data, ARM, READING, 0.1, None)
    x, _ = problem.solve(names, {**start, "stiffening_exponent": 1.5})
    values = {**start, **dict(zip(names, x.tolist(), strict=True))}
    masks = []
    for part in np.array_split(np.arange(data.trials), 4):
        keep = np.ones(data.trials, bool)
        keep[part] = False
        masks.append(np.broadcast_to(keep[:, None], problem.use.shape))
    return problem, names, values, masks


def _costs(problem: Problem, names: list[str], values: dict[str, float],
           masks: list[np.ndarray], points: np.ndarray) -> np.ndarray:
    return np.array([half_square(problem.residuals(problem.predicted(names, values, x), m))
                     for x, m in zip(points, masks, strict=True)])


def test_every_refit_ends_at_or_below_its_starting_cost(
        fitted: tuple[Problem, list[str], dict[str, float], list[np.ndarray]],
        monkeypatch: pytest.MonkeyPatch) -> None:
    """With halved steps each block's refit lowers its cost; full steps alone raise it."""
    problem, names, values, masks = fitted
    solution = np.array([[values[n] for n in names]] * len(masks))
    before = _costs(problem, names, values, masks, solution)
    after = _costs(problem, names, values, masks, problem.refits(names, values, masks, [3] * 4))
    assert np.all(after <= before)
    monkeypatch.setattr(problem_module, "STEP_HALVINGS", 0)
    refused = problem.refits(names, values, masks, [1] * 4)  # the full first step, or none
    assert np.any(np.all(refused == solution, axis=1))
