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
sensor frame period           128.5 µs                  the adapter firmware's figure for
                                                        one complete frame (~7.8 kHz): the
                                                        frame counter's unit
emulate filter                on                        the adapter's low-pass (cut-off set by
                                                        the host) on signal and noise
============================  ========================  ====================================

Randomness comes from one seeded ``numpy.random.Generator``; ``state_dict``
and ``load_state_dict`` save and restore it with the bias and offset, so a
resumed run is bit-identical.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from forcelearn.deprecation import renamed
from forcelearn.protocols.jr3_can.opcodes import SENSOR_FRAME_PERIOD_S
from forcelearn.protocols.jr3_can.scaling import INT16_MAX, INT16_MIN, counts_per_unit

Six = tuple[float, float, float, float, float, float]


@dataclass(frozen=True)
class Jr3ModelParams:
    """The emulated sensor: full scales (N, N*m), noise, bias and drift per axis."""

    full_scales: Six = (200.0, 200.0, 400.0, 20.0, 20.0, 20.0)
    noise_std: Six = (0.2, 0.2, 0.2, 0.02, 0.02, 0.02)
    initial_bias: Six = (1.5, -2.0, 3.0, 0.05, -0.08, 0.03)
    bias_drift_per_sqrt_s: Six = (0.02, 0.02, 0.02, 0.002, 0.002, 0.002)
    zero_average_samples: int = 16
    sync_sample_period_s: float = SENSOR_FRAME_PERIOD_S
    """One complete 6-axis frame of the sensor, s: the frame counter's unit (128.5 µs, the
    adapter firmware's figure, ~7.8 kHz)."""
    emulate_filter: bool = True
    """Apply the adapter's low-pass at the host's cut-off to the signal and the noise."""

    def __post_init__(self) -> None:
        for name in ("full_scales", "noise_std", "initial_bias", "bias_drift_per_sqrt_s"):
            if len(getattr(self, name)) != 6:
                raise ValueError(f"sensor model {name} needs 6 values (Fx..Mz)")
            if not all(math.isfinite(v) for v in getattr(self, name)):
                raise ValueError(f"sensor model {name} must be finite")
        if any(fs <= 0 or fs * 10 > 0xFFFF for fs in self.full_scales):
            raise ValueError("sensor model full_scales must be > 0 and fit the adapter's uint16")
        if min(self.noise_std) < 0 or min(self.bias_drift_per_sqrt_s) < 0:
            raise ValueError("sensor model noise_std and bias_drift_per_sqrt_s must be >= 0")
        if self.zero_average_samples < 1 or not (
            math.isfinite(self.sync_sample_period_s) and self.sync_sample_period_s > 0
        ):
            raise ValueError("sensor model zero_average_samples >= 1, sync_sample_period_s > 0")


class Jr3SensorModel:
    """Noise, drifting bias, offset and quantisation of one emulated sensor.

    Args:
        params: the sensor model.
        rng: the generator every random draw comes from.
    """

    def __init__(self, params: Jr3ModelParams, rng: np.random.Generator) -> None:
        self.params = params
        self.rng = rng
        # Plain floats, not 6-element arrays: one sample is a dozen operations per axis, and
        # numpy's per-call overhead on six numbers is several times the arithmetic.
        self._counts_per_unit = counts_per_unit(params.full_scales)
        self._noise = [float(v) for v in params.noise_std]
        self._drift = [float(v) for v in params.bias_drift_per_sqrt_s]
        self._filter = params.emulate_filter
        self._bias = [float(v) for v in params.initial_bias]
        self._offset = [0.0] * 6
        self._lowpass: list[float] | None = None
        self._filtered_noise = [0.0] * 6
        self._draws = np.empty(12)
        """Where each sample's 12 normal draws go (noise, then bias steps)."""
        self._filter_terms = (-1.0, -1.0, 0.0, 0.0, 0.0)
        """(cut-off Hz, dt s, keep, 1 - keep, sqrt(1 - keep^2)) of the last filtered sample."""

    @property
    def bias(self) -> np.ndarray:
        """The sensor's present bias (6,), N and N*m (a random walk)."""
        return np.array(self._bias)

    @property
    def offset(self) -> np.ndarray:
        """The offset stored by the last zeroing (6,), N and N*m."""
        return np.array(self._offset)

    @property
    def lowpass(self) -> np.ndarray | None:
        """The adapter filter's output of the true wrench (None: not started)."""
        return None if self._lowpass is None else np.array(self._lowpass)

    @property
    def noise(self) -> np.ndarray:
        """The filtered noise at the adapter's output (6,)."""
        return np.array(self._filtered_noise)

    def measure(self, true_wrench: np.ndarray | Sequence[float], dt_s: float,
                cutoff_hz: float = 0.0) -> list[int]:
        """Return six int16 counts for one sample, ``dt_s`` after the previous one.

        ``true_wrench``: six numbers, N and N*m (an array or floats). ``cutoff_hz`` is
        the adapter's low-pass cut-off (0: no filter). Each axis is computed in the
        order the module docstring writes it (the six axes written out: a hot path).
        """
        d = self.rng.standard_normal(out=self._draws).tolist()  # the 12 draws, no new array
        true = true_wrench.tolist() if isinstance(true_wrench, np.ndarray) else true_wrench
        root_dt = dt_s**0.5
        b, w = self._bias, self._drift
        bias = [b[0] + w[0] * root_dt * d[6], b[1] + w[1] * root_dt * d[7],
                b[2] + w[2] * root_dt * d[8], b[3] + w[3] * root_dt * d[9],
                b[4] + w[4] * root_dt * d[10], b[5] + w[5] * root_dt * d[11]]
        s, low = self._noise, self._lowpass
        if self._filter and cutoff_hz > 0 and low is not None:
            terms = self._filter_terms
            if terms[0] != cutoff_hz or terms[1] != dt_s:  # the same dt nearly every sample
                keep = math.exp(-2.0 * math.pi * cutoff_hz * dt_s)
                self._filter_terms = terms = (cutoff_hz, dt_s, keep, 1.0 - keep,
                                              math.sqrt(1.0 - keep * keep))
            _, _, keep, rest, spread = terms
            f = self._filtered_noise
            low = [keep * low[0] + rest * true[0], keep * low[1] + rest * true[1],
                   keep * low[2] + rest * true[2], keep * low[3] + rest * true[3],
                   keep * low[4] + rest * true[4], keep * low[5] + rest * true[5]]
            noise = [keep * f[0] + s[0] * spread * d[0], keep * f[1] + s[1] * spread * d[1],
                     keep * f[2] + s[2] * spread * d[2], keep * f[3] + s[3] * spread * d[3],
                     keep * f[4] + s[4] * spread * d[4], keep * f[5] + s[5] * spread * d[5]]
        else:
            low = [float(v) for v in true]
            noise = [s[0] * d[0], s[1] * d[1], s[2] * d[2], s[3] * d[3], s[4] * d[4],
                     s[5] * d[5]]
        self._bias, self._filtered_noise, self._lowpass = bias, noise, low
        o, u = self._offset, self._counts_per_unit
        counts = []
        for value in ((low[0] + bias[0] - o[0] + noise[0]) * u[0],  # to_count written out
                      (low[1] + bias[1] - o[1] + noise[1]) * u[1],
                      (low[2] + bias[2] - o[2] + noise[2]) * u[2],
                      (low[3] + bias[3] - o[3] + noise[3]) * u[3],
                      (low[4] + bias[4] - o[4] + noise[4]) * u[4],
                      (low[5] + bias[5] - o[5] + noise[5]) * u[5]):
            counts.append(INT16_MAX if value >= INT16_MAX else
                          INT16_MIN if value <= INT16_MIN else round(value))
        return counts

    def zero(self, true_wrench: np.ndarray) -> None:
        """Store the present reading (noise averaged) as the offset."""
        n = self.params.zero_average_samples
        noise = np.asarray(self._noise) * self.rng.standard_normal((n, 6)).mean(axis=0)
        self._offset = (np.asarray(true_wrench, dtype=float) + self.bias + noise).tolist()

    def restart(self) -> None:
        """The adapter's sensor thread starts again: its filter state is new (offset kept)."""
        self._lowpass = None
        self._filtered_noise = [0.0] * 6

    def power_cycle(self) -> None:
        """Forget the offset, as the adapter does on stop, reset and power-up.

        The bias stays: it is physical.
        """
        self._offset = [0.0] * 6

    def state_dict(self) -> dict[str, Any]:
        """Return the generator state, bias and offset (for bit-identical resume)."""
        return {
            "rng": self.rng.bit_generator.state,
            "bias": self.bias,
            "offset": self.offset,
            "lowpass": self.lowpass,
            "noise": self.noise,
        }

    def load_state_dict(self, state: dict[str, Any]) -> None:
        """Restore a state from :meth:`state_dict`."""
        self.rng.bit_generator.state = state["rng"]
        self._bias = np.asarray(state["bias"], dtype=float).tolist()
        self._offset = np.asarray(state["offset"], dtype=float).tolist()
        lowpass = state.get("lowpass")
        self._lowpass = None if lowpass is None else np.asarray(lowpass, dtype=float).tolist()
        self._filtered_noise = np.asarray(state.get("noise", np.zeros(6)), dtype=float).tolist()


__getattr__ = renamed(__name__, {"SensorModelParams": Jr3ModelParams,
                                 "SensorModel": Jr3SensorModel})
