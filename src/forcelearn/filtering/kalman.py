"""Kalman filter of the normal contact force, on filterpy's ``KalmanFilter``.

Model (one axis, sample period ``dt``)
--------------------------------------
=============  ==========================================================
state x        (force N, force rate N/s)
transition F   [[1, dt], [0, 1]]: the force changes at a constant rate
process Q      filterpy's discrete white-noise model, ``var`` = q in
               (N/s^2)^2: how fast the rate of the force may wander
measurement H  [1, 0]: the sensor reads the force
noise R        the sensor's noise variance on that axis in N^2, from the
               calibration tool once it has measured it, from config before
=============  ==========================================================

A missing sample (a counter gap, or ``update(None)``) is a predict only.

Steps. A contact force jumps when the roller meets the sponge or the robot
steps; a constant-rate model would follow the jump only slowly. When the
innovation exceeds ``jump_gate_sigma`` standard deviations, the filter restarts
at the measurement (rate 0, variance R), so a step is followed with no delay.
The old track is kept for one sample: if the next measurement lies within the
gate of the old track and outside the new one's, the jump was a single wild
sample and the old track is resumed, so one outlier costs one output sample
and never moves the estimate afterwards.
"""

from __future__ import annotations

import math
import threading
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from filterpy.common import Q_discrete_white_noise
from filterpy.kalman import KalmanFilter

from forcelearn.devices import WrenchSample
from forcelearn.errors import ConfigError

COUNTER_MODULUS = 1 << 16
MAX_CACHED_PERIODS = 64
"""Step lengths whose F and Q the stream filter keeps."""
MAX_PREDICT_GAP = 1000
"""Longer gaps (in samples) restart the filter instead of predicting through them."""


@dataclass(frozen=True)
class ForceFilterConfig:
    """Parameters of the force filter (units in the names).

    Attributes:
        model: "moves" (:class:`~forcelearn.filtering.step_filter.MoveAwareForceFilter`,
            for a cell that moves, settles and reads a burst: the §5 task) or
            "stream" (:class:`ForceFilter`, a constant-rate track of a
            continuous stream with jump restart and outlier rejection).
        sample_period_s: time between sensor samples when the samples do not tell it,
            s. A sample that carries the sensor's own time since the previous one
            (``WrenchSample.sensor_dt_s``: a JR3 adapter's frame counter) is filtered
            with that instead. The default is a JR3 adapter in sync mode: one sample per
            1 ms turn of its main loop; a Net F/T's is its RDT period.
        measurement_variance_n2: R, the sensor's noise variance on the axis.
            Default (0.2 N)^2, the emulated JR3's; the calibration tool measures it.
        rate_noise_var: q of the stream model's discrete white-noise model, (N/s^2)^2.
        jump_gate_sigma: innovation, in standard deviations, that signals a
            step (stream) or an outlier (moves).
        axis: which wrench component is the normal force (1 = Fy, the sponge's).
        sign: +1 or -1, so that pressing harder reads larger.
        noise_cutoff_hz: the low-pass cut-off that colours the sensor's noise
            (the adapter's ``cutoff_hz``; 0: white noise), moves model.
        move_change_std_n: how much the force may change across a move when
            nothing predicts it (a wide prior), N, moves model.
        direction: a unit direction (sensor frame) whose force component is the
            normal force, in place of one axis: ``sign * (Fx, Fy, Fz) . direction``
            (a sensor mounted at an angle to the tool's force axis; ``axis`` then names
            the nearest sensor axis, whose noise stands for it). None: ``axis``.
        bias_drift_n_per_sqrt_s: the sensor bias's random walk on the axis, N/sqrt(s)
            (thermal drift: the zero check allows what it drifts since the last zero).
            Default 0.02, the emulated JR3's (a long free-space recording gives a real one's).
        bias_drift_max_n_per_s: the fastest steady drift of the bias the sensor may start
            between two zero checks, N/s (a warming sensor): no check has seen it yet, so the
            press guard keeps this x the time since the zero as headroom when it presses on
            from a reading in contact (:mod:`forcelearn.press_guard`). Default 0.2 (a sensor
            drifting faster fails its zero checks: the run voids and ends on ``ZeroMoved``).
    """

    model: str = "moves"
    sample_period_s: float = 0.001
    measurement_variance_n2: float = 0.04
    rate_noise_var: float = 5.0e4
    jump_gate_sigma: float = 5.0
    axis: int = 1
    sign: float = 1.0
    noise_cutoff_hz: float = 0.0
    move_change_std_n: float = 30.0
    direction: tuple[float, float, float] | None = None
    bias_drift_n_per_sqrt_s: float = 0.02
    bias_drift_max_n_per_s: float = 0.2

    def __post_init__(self) -> None:
        if self.model not in ("moves", "stream"):
            raise ConfigError(f"filter.model={self.model!r}: must be 'moves' or 'stream'")
        for key in ("sample_period_s", "measurement_variance_n2", "rate_noise_var",
                    "jump_gate_sigma", "move_change_std_n"):
            value = getattr(self, key)
            if not (isinstance(value, int | float) and math.isfinite(value) and value > 0):
                raise ConfigError(f"filter.{key}={value!r}: must be a finite number > 0")
        drift = self.bias_drift_n_per_sqrt_s
        if not (isinstance(drift, int | float) and math.isfinite(drift) and drift >= 0):
            raise ConfigError(f"filter.bias_drift_n_per_sqrt_s={drift!r}: must be >= 0")
        fastest = self.bias_drift_max_n_per_s
        if not (isinstance(fastest, int | float) and math.isfinite(fastest) and fastest >= 0):
            raise ConfigError(f"filter.bias_drift_max_n_per_s={fastest!r}: must be >= 0")
        cutoff = self.noise_cutoff_hz
        if not (isinstance(cutoff, int | float) and math.isfinite(cutoff) and cutoff >= 0):
            raise ConfigError(f"filter.noise_cutoff_hz={cutoff!r}: must be >= 0 (0: white)")
        if self.axis not in range(6) or self.sign not in (1.0, -1.0):
            raise ConfigError("filter.axis must be 0..5 and filter.sign +1 or -1")
        if self.direction is not None:
            d = np.asarray(self.direction, dtype=float)
            if d.shape != (3,) or not np.all(np.isfinite(d)) or abs(np.linalg.norm(d) - 1) > 1e-6:
                raise ConfigError(f"filter.direction={self.direction!r}: must be a unit "
                                  "3-vector (sensor frame)")

    def normal_force(self, wrenches: np.ndarray | Sequence[float]) -> np.ndarray:
        """Return the normal force (N), ``sign * wrench[axis]``: pressing harder reads larger.

        Of one wrench (6,), a 0-d array (``float()`` it); of rows (n, 6), an array (n,).
        """
        if self.direction is not None:
            along: np.ndarray = self.sign * (
                np.asarray(wrenches, dtype=float)[..., :3] @ np.asarray(self.direction))
            return along
        result: np.ndarray = self.sign * np.asarray(wrenches, dtype=float)[..., self.axis]
        return result


class ForceFilter:
    """Filter one force axis sample by sample; thread-safe (the driver calls from its thread)."""

    def __init__(self, config: ForceFilterConfig | None = None) -> None:
        self.config = config or ForceFilterConfig()
        self._kf = KalmanFilter(dim_x=2, dim_z=1)
        self._kf.H = np.array([[1.0, 0.0]])
        self._dt = math.nan
        self._models: dict[float, tuple[np.ndarray, np.ndarray]] = {}
        self._set_period(self.config.sample_period_s)
        self._lock = threading.Lock()
        self.set_measurement_variance(self.config.measurement_variance_n2)
        self.reset()

    # ---- state ----------------------------------------------------------
    def reset(self) -> None:
        """Forget everything: the next measurement starts the filter."""
        with self._lock:
            self._started = False
            self._last_counter: int | None = None
            self._fallback: tuple[np.ndarray, np.ndarray] | None = None
            self.jumps = 0

    def set_measurement_variance(self, variance_n2: float) -> None:
        """Set R (N^2), e.g. from the calibration tool's measured noise variance."""
        if not variance_n2 > 0:
            raise ValueError(f"measurement variance must be > 0 N^2, got {variance_n2}")
        with self._lock:
            self._kf.R = np.array([[variance_n2]])

    @property
    def measurement_variance_n2(self) -> float:
        """R: the sensor's noise variance on the axis, N^2."""
        with self._lock:
            return float(self._kf.R[0, 0])

    @property
    def force_n(self) -> float:
        """The filtered force in N (nan before the first measurement)."""
        with self._lock:
            return float(self._kf.x[0, 0]) if self._started else math.nan

    @property
    def rate_n_per_s(self) -> float:
        """The filtered force rate in N/s (nan before the first measurement)."""
        with self._lock:
            return float(self._kf.x[1, 0]) if self._started else math.nan

    # ---- stepping -------------------------------------------------------
    def update(self, measurement_n: float | None) -> float:
        """Advance one sample period; ``None`` means the sample is missing (predict only).

        Returns the filtered force in N (nan until the first measurement).
        """
        with self._lock:
            return self._step(measurement_n)

    def _set_period(self, dt: float) -> None:
        """Use a step of ``dt`` seconds for the next predictions.

        F and Q are kept per step length: a JR3 adapter's samples alternate between two.
        """
        if dt == self._dt:
            return
        self._dt = dt
        cached = self._models.get(dt)
        if cached is None:
            if len(self._models) >= MAX_CACHED_PERIODS:
                self._models.clear()
            cached = (np.array([[1.0, dt], [0.0, 1.0]]),
                      Q_discrete_white_noise(dim=2, dt=dt, var=self.config.rate_noise_var))
            self._models[dt] = cached
        self._kf.F, self._kf.Q = cached

    def on_sample(self, sample: WrenchSample) -> None:
        """Driver callback: filter the configured axis over the time the sample says.

        With the sensor's own time since the previous sample (``sensor_dt_s``), one
        step of that length; without it, one step of ``sample_period_s`` per
        counter step (predicting through gaps).
        """
        z = float(self.config.normal_force(sample.wrench))
        with self._lock:
            if sample.sensor_dt_s is not None:
                self._last_counter = sample.counter
                if sample.sensor_dt_s > MAX_PREDICT_GAP * self.config.sample_period_s:
                    self._started = False
                elif sample.sensor_dt_s > 0:
                    self._set_period(sample.sensor_dt_s)
                self._step(z)
                return
            self._set_period(self.config.sample_period_s)
            if self._last_counter is not None:
                gap = (sample.counter - self._last_counter) % COUNTER_MODULUS - 1
                if gap > MAX_PREDICT_GAP:
                    self._started = False
                else:
                    for _ in range(max(gap, 0)):
                        self._step(None)
            self._last_counter = sample.counter
            self._step(z)

    def _step(self, z: float | None) -> float:
        kf = self._kf
        if not self._started:
            if z is None:
                return math.nan
            self._restart(z)
            return z
        kf.predict()
        fallback, self._fallback = self._fallback, None
        if fallback is not None:
            fallback = self._predicted(*fallback)
        if z is None:
            return float(kf.x[0, 0])
        if not self._within_gate(z, kf.x, kf.P):
            if fallback is not None and self._within_gate(z, *fallback):
                kf.x, kf.P = fallback  # the jump was one wild sample: resume the old track
            else:
                self.jumps += 1
                self._fallback = (kf.x.copy(), kf.P.copy())
                self._restart(z)
                return z
        kf.update(np.array([[z]]))
        return float(kf.x[0, 0])

    def _within_gate(self, z: float, x: np.ndarray, p: np.ndarray) -> bool:
        sigma = math.sqrt(float(p[0, 0] + self._kf.R[0, 0]))
        return abs(z - float(x[0, 0])) <= self.config.jump_gate_sigma * sigma

    def _predicted(self, x: np.ndarray, p: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Return a (state, covariance) pair moved one period ahead."""
        f, q = self._kf.F, self._kf.Q
        return f @ x, f @ p @ f.T + q

    def _restart(self, z: float) -> None:
        kf = self._kf
        r = float(kf.R[0, 0])
        dt = self._dt
        kf.x = np.array([[z], [0.0]])
        # rate unknown: allow a change of one noise sigma per sample period
        kf.P = np.diag([r, r / dt**2])
        self._started = True
