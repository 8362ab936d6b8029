"""The sensor model's sample (``Jr3SensorModel.measure``) is the per-axis formula, to the bit.

The reference below is the loop as session 9 wrote it (``exp``/``sqrt`` every sample,
``to_count`` per axis); the model keeps the filter's terms per (cut-off, dt) and writes
``to_count`` out.
"""

from __future__ import annotations

import math
import random

import numpy as np

from forcelearn.emulators.jr3.sensor_model import Jr3ModelParams, Jr3SensorModel
from forcelearn.protocols.jr3_can.scaling import to_count


class _Reference:
    """The sample by the docstring's formula, with its own copy of the state."""

    def __init__(self, model: Jr3SensorModel) -> None:
        self.model = model
        self.bias = list(model._bias)
        self.filtered = [0.0] * 6
        self.lowpass: list[float] | None = None

    def measure(self, true: list[float], dt_s: float, cutoff_hz: float,
                draws: list[float]) -> list[int]:
        model, root_dt = self.model, dt_s**0.5
        filtering = model._filter and cutoff_hz > 0 and self.lowpass is not None
        lowpass = list(true) if self.lowpass is None or not filtering else self.lowpass
        counts = []
        for axis in range(6):
            self.bias[axis] = self.bias[axis] + model._drift[axis] * root_dt * draws[6 + axis]
            if filtering:
                keep = math.exp(-2.0 * math.pi * cutoff_hz * dt_s)
                low = keep * lowpass[axis] + (1.0 - keep) * true[axis]
                n = (keep * self.filtered[axis]
                     + model._noise[axis] * math.sqrt(1.0 - keep * keep) * draws[axis])
            else:
                low = float(true[axis])
                n = model._noise[axis] * draws[axis]
            lowpass[axis], self.filtered[axis] = low, n
            counts.append(to_count((low + self.bias[axis] - model._offset[axis] + n)
                                   * model._counts_per_unit[axis]))
        self.lowpass = lowpass
        return counts


def test_samples_are_the_formula_to_the_bit() -> None:
    """Filter on and off, cut-offs and spacings changing, saturation both ways, 4,000 samples."""
    rng = random.Random(11)
    for emulate_filter in (True, False):
        params = Jr3ModelParams(emulate_filter=emulate_filter)
        model = Jr3SensorModel(params, np.random.default_rng(2))
        reference = _Reference(model)
        twin = np.random.default_rng(2)  # the draws the model takes, taken again
        for i in range(2000):
            if i % 500 == 0:
                model.zero(np.zeros(6))
                twin.standard_normal((params.zero_average_samples, 6))
            if i % 300 == 7:
                model.restart()
                reference.lowpass, reference.filtered = None, [0.0] * 6
            scale = rng.choice((1.0, 50.0, 5000.0))  # the last saturates the int16 counts
            true = [rng.uniform(-scale, scale) for _ in range(6)]
            dt = rng.choice((0.001, 0.001, 0.0001285, rng.uniform(1e-5, 0.05)))
            cutoff = rng.choice((0.0, 500.0, 500.0, 31.25))
            expected = reference.measure(true, dt, cutoff, twin.standard_normal(12).tolist())
            assert model.measure(np.array(true), dt, cutoff) == expected, i
            assert (model._bias, model._filtered_noise, model._lowpass) == (
                reference.bias, reference.filtered, reference.lowpass), i
