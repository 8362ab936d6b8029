"""A friction the family does not fit (a tool reading along the normal) widens the shape.

The slope's wave carries the friction's share of the reading, so the waviness and the
stiffness field make up for a friction the chosen member lacks (hidden cell 16 of seed 2,
friction 0.35: the waviness's wavelength 81.20 +- 0.25 mm against 80, +4.7 sigma).
"""

from __future__ import annotations

import dataclasses
from types import SimpleNamespace

import numpy as np

from forcelearn.emulators.jr3.sensor_model import Jr3ModelParams
from forcelearn.emulators.physics.sponge import SpongeParams
from forcelearn.tools.twin.arrays import to_arrays
from forcelearn.tools.twin.forward import Reading
from forcelearn.tools.twin.params import Member
from forcelearn.tools.twin.problem import Problem
from forcelearn.tools.twin.simulate import DOWN, SimulatedRun, simulate_run
from forcelearn.tools.twin.unfitted import unfitted_spread

ARM = {"start_delay_s": 0.05, "accel_mm_s2": 1000.0, "default_speed_mm_s": 100.0,
       "lag_s": 0.03}
READING = Reading.of(DOWN, 1, -1.0)
QUIET = Jr3ModelParams(noise_std=(0.05,) * 6, initial_bias=(0.0,) * 6,
                       bias_drift_per_sqrt_s=(0.0,) * 6)
CELL = SpongeParams(surface_y_mm=0.5, surface_slope=0.03, stiffness_n_per_mm=1.3,
                    relaxation_ratio=0.0, softening=0.0, set_mm=0.0)
MEMBER = Member("shape", ("surface_y_mm", "surface_slope", "waviness_mm",
                          "waviness_wavelength_mm", "stiffness_n_per_mm", "stiffness_variation",
                          "stiffness_wavelength_mm"))
NAMES = list(MEMBER.free)
SHAPES = ("waviness_wavelength_mm", "stiffness_wavelength_mm")


def _fit(friction: float) -> tuple[dict[str, float], np.ndarray, dict[str, float]]:
    """The shape member fitted to a cell of ``friction``: values, sandwich 1-sigma, share."""
    cell = dataclasses.replace(CELL, friction_coefficient=friction)
    records = simulate_run(SimulatedRun(trials=30, sponge=cell, sensor=QUIET,
                                        probe_points=(0.0, 0.5, 1.0, 0.25, 0.75)), seed=3)
    data = to_arrays(records)
    values = {k: float(v) for k, v in dataclasses.asdict(CELL).items()}
    problem = Problem(data, ARM, READING, 0.05)
    x, result = problem.solve(NAMES, values)
    solved = {**values, **dict(zip(NAMES, x.tolist(), strict=True))}
    fitted = SimpleNamespace(member=MEMBER, values=solved, held=())
    share = unfitted_spread(fitted, (MEMBER,), data, ARM, READING, 0.05)
    return solved, problem.sigmas(result.jac, result.fun), share


def test_a_friction_left_out_is_in_the_wavelengths_sigma() -> None:
    """Friction 0.3: the wavelengths are beyond 3 of the fit's sigmas; with the share, within."""
    solved, one_sigma, share = _fit(0.3)
    for name in SHAPES:
        error = abs(solved[name] - getattr(CELL, name))
        assert error > 3 * one_sigma[NAMES.index(name)]  # what the fit said before
        assert error < 3 * np.hypot(one_sigma[NAMES.index(name)], share[name])


def test_no_friction_adds_nothing() -> None:
    """A cell without friction: the records do not want one, and nothing is added."""
    _, _, share = _fit(0.0)
    assert share == {}
