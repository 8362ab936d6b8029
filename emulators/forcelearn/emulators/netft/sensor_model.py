"""The Net F/T transducer as the emulator sees it: true wrench in, int32 counts out.

Description
-----------
Each record turns the noise-free wrench of the shared physics into what the
box sends::

    bias     <- bias + bias_drift_per_sqrt_s * sqrt(dt) * N(0, 1)        (random walk)
    reading   = true + bias + noise_std * N(0, 1)                        (per axis, N, N·m)
    reading   = clip(reading, -saturation, +saturation)                  (gauges saturate)
    counts    = round((reading - software_bias) * counts_per_si)          (int32)

``counts_per_si`` is counts per unit divided by the unit in SI (N or N·m), so
quantisation (one count = 1 / counts_per_force of a unit) and the unit
encoding come from the box's calibration, not from a full scale as on the JR3
(16384 counts per full scale). "Set software bias" stores the present reading
(noise averaged over ``bias_average_samples``) and subtracts it, as the box does.

Defaults and why
----------------
============================  ==========================  ================================
parameter                     default                     why
============================  ==========================  ================================
counts per unit               1,000,000 per N and N-m     ATI's factory value (cfgcpf/cfgcpt)
ranges                        130, 130, 400 N;            an ATI Gamma SI-130-10 (assumption:
                              10, 10, 10 N·m              a common Net F/T transducer)
saturation                    1.0 x range                 assumption: gauges clip at range
noise std                     0.05 N; 0.0025 N·m          assumption: a few counts of Gamma
                                                          resolution (1/40 N, 1/800 N·m)
initial bias                  0.8, -1.2, 2.0 N;           offsets are not zero at power-up
                              0.03, -0.05, 0.02 N·m
bias drift                    0.01 N/sqrt(s);             thermal drift (assumption), small
                              0.0005 N·m/sqrt(s)          against noise within one step
============================  ==========================  ================================

Units are spelled as a box spells them on its web pages: ``N`` and ``Nm`` (a live
netftapi2.xml says ``<scfgtu>Nm</scfgtu>``; forcelearn's own name ``N-m`` works too).

Randomness comes from one seeded ``numpy.random.Generator``; ``state_dict``
and ``load_state_dict`` carry it with the bias and the software bias, so a
resumed run is bit-identical.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from forcelearn.protocols.netft import FORCE_UNIT_SI, INT32_MAX, INT32_MIN, TORQUE_UNIT_SI

Six = tuple[float, float, float, float, float, float]


@dataclass(frozen=True)
class NetFtModelParams:
    """The emulated transducer and box calibration: units, counts, ranges, noise, bias, drift."""

    counts_per_force: int = 1_000_000
    counts_per_torque: int = 1_000_000
    force_unit: str = "N"
    torque_unit: str = "Nm"
    ranges: Six = (130.0, 130.0, 400.0, 10.0, 10.0, 10.0)
    saturation_fraction: float = 1.0
    noise_std: Six = (0.05, 0.05, 0.05, 0.0025, 0.0025, 0.0025)
    initial_bias: Six = (0.8, -1.2, 2.0, 0.03, -0.05, 0.02)
    bias_drift_per_sqrt_s: Six = (0.01, 0.01, 0.01, 0.0005, 0.0005, 0.0005)
    bias_average_samples: int = 16

    def __post_init__(self) -> None:
        for name in ("ranges", "noise_std", "initial_bias", "bias_drift_per_sqrt_s"):
            if len(getattr(self, name)) != 6:
                raise ValueError(f"netft model {name} needs 6 values (Fx..Tz)")
            if not all(math.isfinite(v) for v in getattr(self, name)):
                raise ValueError(f"netft model {name} must be finite")
        if self.force_unit not in FORCE_UNIT_SI or self.torque_unit not in TORQUE_UNIT_SI:
            raise ValueError(f"netft model units {self.force_unit!r}/{self.torque_unit!r} unknown")
        if not (1 <= self.counts_per_force < math.inf and 1 <= self.counts_per_torque < math.inf):
            raise ValueError("netft model counts per unit must be >= 1")
        if min(self.ranges) <= 0 or not 0 < self.saturation_fraction <= 2:
            raise ValueError("netft model ranges > 0, saturation_fraction in (0, 2]")
        if min(self.noise_std) < 0 or min(self.bias_drift_per_sqrt_s) < 0:
            raise ValueError("netft model noise_std and bias_drift_per_sqrt_s must be >= 0")
        if self.bias_average_samples < 1:
            raise ValueError("netft model bias_average_samples must be >= 1")

    @property
    def counts_per_si(self) -> np.ndarray:
        """Counts per N (Fx, Fy, Fz) and per N·m (Tx, Ty, Tz)."""
        force = self.counts_per_force / FORCE_UNIT_SI[self.force_unit]
        torque = self.counts_per_torque / TORQUE_UNIT_SI[self.torque_unit]
        return np.array([force] * 3 + [torque] * 3)


class NetFtSensorModel:
    """Noise, drifting bias, saturation, software bias and counts of one emulated box.

    Args:
        params: the transducer and calibration.
        rng: the generator every random draw comes from.
    """

    def __init__(self, params: NetFtModelParams, rng: np.random.Generator) -> None:
        self.params = params
        self.rng = rng
        self._counts_per_si = params.counts_per_si
        self._noise = np.asarray(params.noise_std, dtype=float)
        self._drift = np.asarray(params.bias_drift_per_sqrt_s, dtype=float)
        self._saturation = np.asarray(params.ranges, dtype=float) * params.saturation_fraction
        self._floor = -self._saturation
        self.bias = np.asarray(params.initial_bias, dtype=float).copy()
        self.software_bias = np.zeros(6)

    def _reading(self, true_wrench: np.ndarray, dt_s: float) -> np.ndarray:
        draws = self.rng.standard_normal(12)
        self.bias += self._drift * math.sqrt(max(dt_s, 0.0)) * draws[6:]
        reading = true_wrench + self.bias + self._noise * draws[:6]
        # np.clip's values, without its Python-level dispatch (7000 records per s of cell time)
        clipped: np.ndarray = np.minimum(np.maximum(reading, self._floor), self._saturation)
        return clipped

    def measure(self, true_wrench: np.ndarray, dt_s: float) -> tuple[int, ...]:
        """Return six int32 counts for one record, ``dt_s`` after the previous one."""
        reading = self._reading(true_wrench, dt_s)
        counts = ((reading - self.software_bias) * self._counts_per_si).round()
        return tuple(map(int, np.minimum(np.maximum(counts, INT32_MIN), INT32_MAX).tolist()))

    def measure_many(self, true_wrenches: list[np.ndarray],
                     dts_s: list[float]) -> list[tuple[int, ...]]:
        """:meth:`measure` of each wrench in turn, in one numpy pass: the same draws and values.

        The generator's normals are drawn 12 a record in order, and the bias
        walks by ``np.add.accumulate`` (left to right, as one ``+=`` a record),
        so the counts equal those of a :meth:`measure` per record.
        """
        n = len(true_wrenches)
        if n == 0:
            return []
        draws = self.rng.standard_normal((n, 12))
        scale = np.sqrt(np.maximum(np.asarray(dts_s, dtype=float), 0.0))[:, None]
        walk = np.empty((n + 1, 6))
        walk[0] = self.bias
        walk[1:] = self._drift * scale * draws[:, 6:]
        biases = np.add.accumulate(walk, axis=0)[1:]
        self.bias = biases[-1].copy()
        reading = np.vstack(true_wrenches) + biases + self._noise * draws[:, :6]
        clipped = np.minimum(np.maximum(reading, self._floor), self._saturation)
        counts = ((clipped - self.software_bias) * self._counts_per_si).round()
        whole = np.minimum(np.maximum(counts, INT32_MIN), INT32_MAX).tolist()
        return [tuple(map(int, row)) for row in whole]

    def set_software_bias(self, true_wrench: np.ndarray) -> None:
        """Store the present reading (noise averaged) as the software bias."""
        n = self.params.bias_average_samples
        noise = self._noise * self.rng.standard_normal((n, 6)).mean(axis=0)
        self.software_bias = np.clip(true_wrench + self.bias + noise,
                                     -self._saturation, self._saturation)

    def power_cycle(self) -> None:
        """Forget the software bias, as the box does when it boots (the physical bias stays)."""
        self.software_bias = np.zeros(6)

    def state_dict(self) -> dict[str, Any]:
        """Return the generator state, bias and software bias (for a bit-identical resume)."""
        return {"rng": self.rng.bit_generator.state, "bias": self.bias.copy(),
                "software_bias": self.software_bias.copy()}

    def load_state_dict(self, state: dict[str, Any]) -> None:
        """Restore a state from :meth:`state_dict`."""
        self.rng.bit_generator.state = state["rng"]
        self.bias = np.asarray(state["bias"], dtype=float).copy()
        self.software_bias = np.asarray(state["software_bias"], dtype=float).copy()
