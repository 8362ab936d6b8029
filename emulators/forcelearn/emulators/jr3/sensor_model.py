"""The JR3 sensor as the emulator sees it: true wrench in, 16-bit counts out.

Description
-----------
Each sample turns the noise-free wrench of the shared physics into what the
adapter would send::

    bias    <- bias + bias_drift_per_sqrt_s * sqrt(dt) * N(0, 1)      (random walk)
    reading  = true + bias - offset + noise_std * N(0, 1)             (per axis)
    counts   = clip(round(reading * 16384 / full_scale), -32768, 32767)

so quantisation (one count = full_scale / 16384) and saturation (the int16
range, about 2 x full scale) come from the encoding itself. Zeroing stores the
present reading as the offset, averaged over ``zero_average_samples`` draws as
the adapter's low-pass would. The adapter's own low-pass is not modelled:
``noise_std`` is the noise at the adapter's output.

Defaults and why
----------------
============================  ========================  ====================================
parameter                     default                   why
============================  ========================  ====================================
full scales                   200, 200, 400 N;          a JR3 67M25-class sensor; 1 count is
                              20, 20, 20 N*m            0.012 N on Fx, Fy (the sponge axis)
noise std                     0.2 N; 0.02 N*m           electronics plus a roller vibrating
                                                        on foam; the paper stresses noise
initial bias                  1.5, -2.0, 3.0 N;         JR3 offsets are not zeroed at power-up
                              0.05, -0.08, 0.03 N*m
bias drift                    0.02 N/sqrt(s);           thermal drift: ~0.2 N over 100 s, small
                              0.002 N*m/sqrt(s)         against noise within one step
sync sample period            1 ms                      the drift clock in sync mode (no wall
                                                        clock, so runs are reproducible)
============================  ========================  ====================================

Randomness comes from one seeded ``numpy.random.Generator``; ``state_dict``
and ``load_state_dict`` save and restore it with the bias and offset, so a
resumed run is bit-identical.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from forcelearn.drivers.jr3_can.scaling import COUNTS_PER_FULL_SCALE, INT16_MAX, INT16_MIN

Six = tuple[float, float, float, float, float, float]


@dataclass(frozen=True)
class SensorModelParams:
    """The emulated sensor: full scales (N, N*m), noise, bias and drift per axis."""

    full_scales: Six = (200.0, 200.0, 400.0, 20.0, 20.0, 20.0)
    noise_std: Six = (0.2, 0.2, 0.2, 0.02, 0.02, 0.02)
    initial_bias: Six = (1.5, -2.0, 3.0, 0.05, -0.08, 0.03)
    bias_drift_per_sqrt_s: Six = (0.02, 0.02, 0.02, 0.002, 0.002, 0.002)
    zero_average_samples: int = 16
    sync_sample_period_s: float = 0.001

    def __post_init__(self) -> None:
        for name in ("full_scales", "noise_std", "initial_bias", "bias_drift_per_sqrt_s"):
            if len(getattr(self, name)) != 6:
                raise ValueError(f"sensor model {name} needs 6 values (Fx..Mz)")
        if any(fs <= 0 or fs * 10 > 0xFFFF for fs in self.full_scales):
            raise ValueError("sensor model full_scales must be > 0 and fit the adapter's uint16")
        if min(self.noise_std) < 0 or min(self.bias_drift_per_sqrt_s) < 0:
            raise ValueError("sensor model noise_std and bias_drift_per_sqrt_s must be >= 0")
        if self.zero_average_samples < 1 or self.sync_sample_period_s <= 0:
            raise ValueError("sensor model zero_average_samples >= 1, sync_sample_period_s > 0")


class SensorModel:
    """Noise, drifting bias, offset and quantisation of one emulated sensor.

    Args:
        params: the sensor model.
        rng: the generator every random draw comes from.
    """

    def __init__(self, params: SensorModelParams, rng: np.random.Generator) -> None:
        self.params = params
        self.rng = rng
        self._counts_per_unit = COUNTS_PER_FULL_SCALE / np.asarray(params.full_scales, dtype=float)
        self._noise = np.asarray(params.noise_std, dtype=float)
        self._drift = np.asarray(params.bias_drift_per_sqrt_s, dtype=float)
        self.bias = np.asarray(params.initial_bias, dtype=float).copy()
        self.offset = np.zeros(6)

    def measure(self, true_wrench: np.ndarray, dt_s: float) -> list[int]:
        """Return six int16 counts for one sample, ``dt_s`` after the previous one."""
        draws = self.rng.standard_normal(12)
        self.bias += self._drift * (dt_s**0.5) * draws[6:]
        reading = true_wrench + self.bias - self.offset + self._noise * draws[:6]
        counts = (reading * self._counts_per_unit).round().clip(INT16_MIN, INT16_MAX)
        return [int(c) for c in counts]

    def zero(self, true_wrench: np.ndarray) -> None:
        """Store the present reading (noise averaged) as the offset."""
        n = self.params.zero_average_samples
        noise = self._noise * self.rng.standard_normal((n, 6)).mean(axis=0)
        self.offset = true_wrench + self.bias + noise

    def power_cycle(self) -> None:
        """Forget the offset, as the adapter does on reboot (the bias stays: it is physical)."""
        self.offset = np.zeros(6)

    def state_dict(self) -> dict[str, Any]:
        """Return the generator state, bias and offset (for bit-identical resume)."""
        return {
            "rng": self.rng.bit_generator.state,
            "bias": self.bias.copy(),
            "offset": self.offset.copy(),
        }

    def load_state_dict(self, state: dict[str, Any]) -> None:
        """Restore a state from :meth:`state_dict`."""
        self.rng.bit_generator.state = state["rng"]
        self.bias = np.asarray(state["bias"], dtype=float).copy()
        self.offset = np.asarray(state["offset"], dtype=float).copy()
