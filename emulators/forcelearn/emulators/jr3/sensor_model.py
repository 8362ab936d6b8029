"""The JR3 sensor as the emulator sees it: true wrench in, 16-bit counts out.

Description
-----------
Each sample turns the noise-free wrench of the shared physics into what the
adapter would send::

    bias    <- bias + bias_drift_per_sqrt_s * sqrt(dt) * N(0, 1)      (random walk)
    keep     = exp(-2 pi cutoff_hz dt)                                  (adapter low-pass)
    lowpass <- keep * lowpass + (1 - keep) * true
    noise   <- keep * noise + noise_std * sqrt(1 - keep^2) * N(0, 1)
    reading  = lowpass + bias - offset + noise                          (per axis)
    counts   = clip(round(reading * 16384 / full_scale), -32768, 32767)

``dt`` is the simulated time since the previous sample. The adapter's
first-order low-pass at the host's ``cutoff_hz`` acts on the true wrench and
on the noise alike: ``noise_std`` is the noise at the adapter's output, and
samples closer together than ~1/(2 pi cutoff_hz) share most of it (an
Ornstein-Uhlenbeck process, exact for any spacing). With the filter off
(``emulate_filter = False`` or cut-off 0) the reading follows the true wrench
at once and the noise is white. Quantisation (one count = full_scale / 16384)
and saturation (the int16 range, about 2 x full scale) come from the encoding
itself. Zeroing stores the present reading as the offset, averaged over
``zero_average_samples`` draws as the adapter's low-pass would.

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
sync sample period            125 µs                    the JR3's 8 kHz DSP rate: two samples
                                                        are never closer than this
emulate filter                on                        the adapter's low-pass (cut-off set by
                                                        the host) on signal and noise
============================  ========================  ====================================

Randomness comes from one seeded ``numpy.random.Generator``; ``state_dict``
and ``load_state_dict`` save and restore it with the bias and offset, so a
resumed run is bit-identical.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from forcelearn.protocols.jr3_can.scaling import COUNTS_PER_FULL_SCALE, INT16_MAX, INT16_MIN

Six = tuple[float, float, float, float, float, float]


@dataclass(frozen=True)
class SensorModelParams:
    """The emulated sensor: full scales (N, N*m), noise, bias and drift per axis."""

    full_scales: Six = (200.0, 200.0, 400.0, 20.0, 20.0, 20.0)
    noise_std: Six = (0.2, 0.2, 0.2, 0.02, 0.02, 0.02)
    initial_bias: Six = (1.5, -2.0, 3.0, 0.05, -0.08, 0.03)
    bias_drift_per_sqrt_s: Six = (0.02, 0.02, 0.02, 0.002, 0.002, 0.002)
    zero_average_samples: int = 16
    sync_sample_period_s: float = 0.000125
    """The sensor's internal sample period, s (JR3: 8 kHz)."""
    emulate_filter: bool = True
    """Apply the adapter's low-pass at the host's cut-off to the signal and the noise."""

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
        self.lowpass: np.ndarray | None = None
        """The adapter filter's output of the true wrench (None: not started)."""
        self.noise = np.zeros(6)
        """The filtered noise at the adapter's output."""

    def measure(self, true_wrench: np.ndarray, dt_s: float, cutoff_hz: float = 0.0) -> list[int]:
        """Return six int16 counts for one sample, ``dt_s`` after the previous one.

        ``cutoff_hz`` is the adapter's low-pass cut-off (0: no filter).
        """
        draws = self.rng.standard_normal(12)
        self.bias += self._drift * (dt_s**0.5) * draws[6:]
        if self.params.emulate_filter and cutoff_hz > 0 and self.lowpass is not None:
            keep = math.exp(-2.0 * math.pi * cutoff_hz * dt_s)
            self.lowpass = keep * self.lowpass + (1.0 - keep) * true_wrench
            self.noise = keep * self.noise + self._noise * math.sqrt(1.0 - keep * keep) * draws[:6]
        else:
            self.lowpass = np.asarray(true_wrench, dtype=float).copy()
            self.noise = self._noise * draws[:6]
        reading = self.lowpass + self.bias - self.offset + self.noise
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
            "lowpass": None if self.lowpass is None else self.lowpass.copy(),
            "noise": self.noise.copy(),
        }

    def load_state_dict(self, state: dict[str, Any]) -> None:
        """Restore a state from :meth:`state_dict`."""
        self.rng.bit_generator.state = state["rng"]
        self.bias = np.asarray(state["bias"], dtype=float).copy()
        self.offset = np.asarray(state["offset"], dtype=float).copy()
        lowpass = state.get("lowpass")
        self.lowpass = None if lowpass is None else np.asarray(lowpass, dtype=float).copy()
        self.noise = np.asarray(state.get("noise", np.zeros(6)), dtype=float).copy()
