"""A member whose periodic shapes ended away from the start is refitted with them put back.

Hidden cell 26 of seed 10 (a linear foam at 0.61 N/mm): the fit traded the waviness for another
wavelength (0.19 mm over 44 mm against 1.0 over 80) and reported it determined at -41 and -79
sigma; from its own solution with the shapes at the start's it fits every value at the truth.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

from forcelearn.emulators.physics.sponge import SpongeParams
from forcelearn.tools.twin import fit as fitting
from forcelearn.tools.twin.arrays import to_arrays
from forcelearn.tools.twin.forward import Reading
from forcelearn.tools.twin.params import HYSTERETIC_MEMBER
from forcelearn.tools.twin.simulate import DOWN, SimulatedRun, simulate_run

READING = Reading.of(DOWN, 1, -1.0)
ARM = {"start_delay_s": 0.05, "accel_mm_s2": 1000.0, "default_speed_mm_s": 100.0,
       "lag_s": 0.03}


@pytest.mark.parametrize(("waviness_mm", "gain", "restarted", "kept"), [
    (0.19, 50.0, True, True),   # moved, and the restart fits better: kept, with a note
    (0.19, 0.5, True, False),   # moved, the restart no better than START_COST: the first fit
    (1.02, 50.0, False, False),  # within SHAPE_KEPT of the start: not tried
])
def test_the_shapes_are_restarted_from_the_start_where_they_moved(
        monkeypatch: pytest.MonkeyPatch, waviness_mm: float, gain: float, restarted: bool,
        kept: bool) -> None:
    """From the fit's own solution with the shapes at the start's; the lower cost is kept."""
    records = simulate_run(SimulatedRun(trials=3, steps=4, burst_samples=5), seed=1)
    data = to_arrays(records)
    train, heldout = data.rows(np.array([0, 1])), data.rows(np.array([2]))
    start = {k: float(v) for k, v in SpongeParams().__dict__.items()}
    first = fitting.fit_member(HYSTERETIC_MEMBER, train, heldout, start, start, ARM, READING,
                               0.05)
    # the stiffness's shape at the start's: two noiseless trials leave it loose (the fit ends
    # anywhere it likes), and only the waviness is the case here
    first.values = {**first.values, "waviness_mm": waviness_mm,
                    "waviness_wavelength_mm": 44.0 if waviness_mm < 0.5 else 80.0,
                    "stiffness_variation": start["stiffness_variation"],
                    "stiffness_wavelength_mm": start["stiffness_wavelength_mm"]}
    first.train_cost = 100.0
    starts: list[dict[str, float]] = []
    real = fitting.fit_member

    def refit(member: Any, train: Any, heldout: Any, point: dict[str, float], *args: Any,
              **kwargs: Any) -> Any:
        starts.append(point)
        again = real(member, train, heldout, point, *args, **kwargs)
        again.train_cost = 100.0 - gain
        return again

    monkeypatch.setattr(fitting, "fit_member", refit)
    result = fitting.shape_restarted(first, train, heldout, start, start, ARM, READING, 0.05)
    assert bool(starts) == restarted
    if restarted:
        point = starts[0]
        assert point["waviness_mm"] == start["waviness_mm"]
        assert point["waviness_wavelength_mm"] == start["waviness_wavelength_mm"]
        assert point["surface_y_mm"] == first.values["surface_y_mm"]  # the rest: its solution
    assert (result is not first) == kept
    assert ("shapes at the start's" in result.note) == kept


def test_first_held_parameters_wait_for_a_first_solve_of_the_rest(
        monkeypatch: pytest.MonkeyPatch) -> None:
    """``first_held``: a first solve without them (they stay at the start's), then all."""
    from forcelearn.tools.twin.problem import Problem

    records = simulate_run(SimulatedRun(trials=3, steps=4, burst_samples=5), seed=1)
    data = to_arrays(records)
    train, heldout = data.rows(np.array([0, 1])), data.rows(np.array([2]))
    start = {k: float(v) for k, v in SpongeParams().__dict__.items()}
    solves: list[tuple[list[str], dict[str, float]]] = []
    real = Problem.solve

    def logged(self: Problem, names: list[str], values: dict[str, float], *args: Any,
               **kwargs: Any) -> Any:
        solves.append((list(names), dict(values)))
        return real(self, names, values, *args, **kwargs)

    monkeypatch.setattr(Problem, "solve", logged)
    shapes = tuple(fitting.SHAPES)
    fitting.fit_member(HYSTERETIC_MEMBER, train, heldout, start, start, ARM, READING, 0.05,
                       first_held=shapes)
    (first_names, first_values), (second_names, second_values) = solves[:2]
    assert not set(shapes) & set(first_names)
    assert set(shapes) <= set(second_names)
    assert all(second_values[n] == start[n] for n in shapes)  # still the start's
    assert second_values["surface_y_mm"] != first_values["surface_y_mm"]  # the rest moved
