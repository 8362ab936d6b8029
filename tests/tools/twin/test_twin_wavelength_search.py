"""A strip whose shapes repeat elsewhere than the defaults' is found by a wavelength search.

Hidden cell 10 of seed 11 (waviness over 160 mm, stiffness variation over 67 mm): from the
emulator's default shapes (80 mm, 120 mm) the least squares locked onto other periods and every
member failed its own train trials; started with one wavelength moved, the same solve reaches
the strip's own.
"""

from __future__ import annotations

import dataclasses
from typing import Any

import pytest

from forcelearn.emulators.physics.sponge import SpongeParams
from forcelearn.tools.twin import fit as fitting
from forcelearn.tools.twin.arrays import to_arrays
from forcelearn.tools.twin.forward import Reading
from forcelearn.tools.twin.params import family
from forcelearn.tools.twin.problem import Problem
from forcelearn.tools.twin.simulate import DOWN, SimulatedRun, simulate_run
from forcelearn.tools.twin.wavelength_search import WAVELENGTHS_MM, best_wavelength_start

READING = Reading.of(DOWN, 1, -1.0)
ARM = {"start_delay_s": 0.05, "accel_mm_s2": 1000.0, "default_speed_mm_s": 100.0,
       "lag_s": 0.03}
STRIP = dataclasses.replace(SpongeParams(), waviness_mm=1.5, waviness_wavelength_mm=160.0,
                            stiffness_variation=0.1, stiffness_wavelength_mm=67.0,
                            relaxation_ratio=0.0)
"""A linear-elastic strip with its own shapes (noiseless runs)."""


@pytest.fixture(scope="module")
def problem() -> Problem:
    """A noiseless 4-trial run on :data:`STRIP`."""
    records = simulate_run(SimulatedRun(trials=4, steps=20, burst_samples=5, sponge=STRIP),
                           seed=1)
    return Problem(to_arrays(records), ARM, READING, 0.05, None)


def test_the_search_finds_the_strips_own_wavelengths_where_the_default_start_does_not(
        problem: Problem) -> None:
    """From the defaults the solve ends on other periods; the search's best is the strip's."""
    member = family()[0]  # linear-elastic: the strip's own member
    names = [n for n in member.free if n not in dict(member.fixed)]
    start = {k: float(v) for k, v in SpongeParams().__dict__.items()}
    x, plain = problem.solve(names, start)
    ended = dict(zip(names, x.tolist(), strict=True))
    assert abs(ended["waviness_wavelength_mm"] / STRIP.waviness_wavelength_mm - 1) > 0.2
    found = best_wavelength_start(problem, names, start)
    assert found is not None
    cost, values = found
    assert cost < plain.cost / 5
    for name in ("waviness_wavelength_mm", "stiffness_wavelength_mm"):
        assert values[name] == pytest.approx(getattr(STRIP, name), rel=0.02)


def test_no_search_without_a_wavelength_to_move(problem: Problem) -> None:
    """A member without the shapes' wavelengths free has nothing to search."""
    start = {k: float(v) for k, v in SpongeParams().__dict__.items()}
    assert best_wavelength_start(problem, ["surface_y_mm", "stiffness_n_per_mm"], start) is None


@pytest.mark.parametrize(("represented", "moved", "searched"),
                         [(False, False, True), (True, True, True), (True, False, False)])
def test_a_member_that_misses_its_train_trials_or_left_the_shapes_is_searched(
        monkeypatch: pytest.MonkeyPatch, represented: bool, moved: bool, searched: bool) -> None:
    """A member's wavelengths are searched when its fit misses or moved them.

    (The train RMS above twice the noise: :func:`~forcelearn.tools.twin.fit.represents`;
    a wavelength more than ``SHAPE_KEPT`` from where it began: :func:`~.fit.wavelengths_moved`.)
    A member that represents them with the wavelengths where they began (the default run's) is
    not.
    """
    calls: list[int] = []

    def searched_fit(fit: Any, *args: Any, **kwargs: Any) -> Any:
        calls.append(1)
        return fit

    monkeypatch.setattr(fitting, "wavelength_searched", searched_fit)
    monkeypatch.setattr(fitting, "represents", lambda fit, noise_n: represented)
    monkeypatch.setattr(fitting, "wavelengths_moved",
                        lambda fit, start: ["waviness_mm"] if moved else [])
    records = simulate_run(SimulatedRun(trials=3, steps=4, burst_samples=5), seed=1)
    data = to_arrays(records)
    base = {k: float(v) for k, v in SpongeParams().__dict__.items()}
    fitting.fit_nested((family()[0],), data.rows([0, 1]), data.rows([2]), base, base, ARM,
                       READING, 0.05)
    assert bool(calls) == searched
    assert len(WAVELENGTHS_MM) >= 5
