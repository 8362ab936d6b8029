"""The sponge fit stops at the cost's resolution (problem.COST_RESOLUTION), not at 1e-8 of it."""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from forcelearn.emulators.physics.sponge import SpongeParams
from forcelearn.tools.twin import problem as fitting_problem
from forcelearn.tools.twin.arrays import to_arrays
from forcelearn.tools.twin.forward import Reading
from forcelearn.tools.twin.problem import COST_RESOLUTION, Problem
from forcelearn.tools.twin.setup import base_arm
from forcelearn.tools.twin.simulate import DOWN, SimulatedRun, noise_only_sensor, simulate_run

READING = Reading.of(DOWN, 1, -1.0)
SLOW_WEAR = SpongeParams(surface_y_mm=0.6, surface_slope=0.02, waviness_mm=0.7,
                         stiffness_n_per_mm=3.2, stiffness_variation=0.1, softening=0.5,
                         softening_passes=2000.0, set_mm=1.5, set_passes=20.0,
                         relaxation_ratio=0.4, relaxation_time_s=0.3)
"""Softening over 2,000 passes seen over 10 trials: only its initial rate is determined, so
the softening and its time constant make a valley the fit may crawl along."""


def test_a_fit_takes_no_step_worth_less_than_the_cost_resolution() -> None:
    """Only the step that ends the fit lowers its cost by less than ``COST_RESOLUTION``."""
    run = SimulatedRun(trials=10, sponge=SLOW_WEAR, sensor=noise_only_sensor(0.3))
    data = to_arrays(simulate_run(run, seed=2))
    names = ["surface_y_mm", "stiffness_n_per_mm", "softening", "softening_passes"]
    values = {k: float(v) for k, v in dataclasses.asdict(SLOW_WEAR).items()}
    values.update(softening=0.05, softening_passes=150.0)
    problem = Problem(data, base_arm(), READING, 0.3)
    points: list[tuple[np.ndarray, float]] = []
    predicted = problem.predicted

    def spy(names_: list[str], frozen: dict[str, float], x: np.ndarray) -> np.ndarray:
        out = predicted(names_, frozen, x)
        residual = problem.residuals(out)
        points.append((x.copy(), 0.5 * float(residual @ residual)))
        return out

    problem.predicted = spy  # type: ignore[method-assign, assignment]
    solution, result = problem.solve(names, values)
    # a trial point moves every value; a finite-difference point one (from the last trial)
    best, small, last = math.inf, 0, None
    for x, cost in points:
        if last is not None and np.count_nonzero(x != last) == 1:
            continue
        last = x
        if cost < best:
            small += best - cost < COST_RESOLUTION
            best = cost
    assert small <= 1, (small, result.nfev)
    assert result.cost <= best + 1e-9
    assert fitting_problem.resolution_ftol(math.inf, 10) == fitting_problem.FTOL
    # the values the records determine are where the full convergence puts them
    assert abs(solution[1] - SLOW_WEAR.stiffness_n_per_mm) < 0.05


def test_a_misfitting_fit_is_resolved_in_its_own_likelihood_units() -> None:
    """Half a chi-square of 100 x its residuals: a unit of log-likelihood is 200 of the cost."""
    residuals = 1000
    for cost in (0.1 * residuals, 100.0 * residuals):
        unit = max(1.0, 2.0 * cost / residuals)
        stop = fitting_problem.resolution_ftol(cost, residuals) * cost
        assert math.isclose(stop, COST_RESOLUTION * unit), (cost, stop)
