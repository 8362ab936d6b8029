"""Kalman filter of the normal force for a cell that moves, settles, then reads a burst.

The §5 task does not stream: after each commanded move the robot settles and
the cell reads a short burst of samples. Between two bursts the contact force
may change by anything from nothing to several newtons, and the cell knows
when that can happen (it commanded the move). Within a burst the force holds
still but the noise is not white: the sensor adapter's low-pass (cut-off
``noise_cutoff_hz``) makes samples a fraction of a millisecond apart share
most of their noise. This filter models both.

Model (filterpy ``KalmanFilter``, one state, one update per burst)
------------------------------------------------------------------
=============  =============================================================
state x        the contact force, N, constant while the cell stands still
move           ``on_move(expected_change_n, change_std_n)``: predict with
               x += expected change, P += change_std^2 (filterpy ``predict``
               with u = the change and Q = its variance)
burst          N samples z_i, ``dt`` apart (the median sensor time between
               them, ``sensor_dt_s``, else ``sample_period_s``), of x plus noise that is a
               first-order (Ornstein-Uhlenbeck) process of variance R and
               sample-to-sample correlation a_i = exp(-2 pi noise_cutoff_hz dt_i)
               (one per gap: the spacing may vary). The burst's information
               about x is exactly its generalised least-squares mean and that
               mean's variance (:func:`burst_mean`); evenly spaced:
               m = [(1-a)(z_1 + z_N) + (1-a)^2 (z_2 + ... + z_N-1)] / D,
               var m = R (1 + a) / (2 + (N - 2)(1 - a)),  D = 2(1-a) + (N-2)(1-a)^2
               (for N = 1: m = z_1, var R). One filterpy ``update`` with z = m
               and R_z = var m.
outliers       samples further than ``jump_gate_sigma`` sqrt(R) from the
               burst's median are left out (counted in ``outliers``)
=============  =============================================================

With no prediction of the change (the default: ``change_std_n`` = the
config's ``move_change_std_n``, 30 N) the estimate after a burst is the
burst's GLS mean, which weighs the samples as their correlation deserves and
is never noisier than their plain mean; its standard deviation depends on the
burst's span far more than on its count (about sqrt(R) sqrt(2 tau / T) for a
span T much longer than tau = 1 / (2 pi cut-off)). With a prediction (a probed
stiffness times the commanded indentation), the previous estimate adds what it
knows. Samples filtered one at a time (``on_sample``) are bursts of one.
"""

from __future__ import annotations

import itertools
import math
import threading
from collections.abc import Sequence

import numpy as np
from filterpy.kalman import KalmanFilter

from forcelearn.devices import WrenchSample
from forcelearn.filtering.kalman import ForceFilterConfig

_UNKNOWN_VAR_N2 = 1.0e8
"""Variance of a force nothing is known about yet (N^2)."""


def burst_mean(
    values: Sequence[float] | np.ndarray, correlation: float | Sequence[float] | np.ndarray
) -> tuple[float, float]:
    """GLS mean of a burst under first-order (Markov) noise of unit variance.

    ``correlation`` is the noise correlation of consecutive samples: one number for
    evenly spaced samples, or one per gap (``len(values) - 1``) when the spacing varies
    (a JR3 adapter's samples are 7 or 8 sensor frames apart). Returns (mean, variance
    factor): the variance of the mean is the noise variance times the factor (1 / N for
    white noise, larger when the correlations are > 0). The weights are the row sums of
    the noise's tridiagonal precision matrix: 1 / (1 + a_1) and 1 / (1 + a_N-1) at the
    ends, 1 / (1 + a_i-1) - a_i / (1 + a_i) between.
    """
    z = np.asarray(values, dtype=float)
    n = len(z)
    if n == 0:
        raise ValueError("a burst needs at least one sample")
    if n == 1:
        return float(z[0]), 1.0
    a = np.asarray(correlation, dtype=float)
    if a.shape != (n - 1,):  # one number for every gap (a burst's own array is used as is)
        a = np.broadcast_to(a, (n - 1,))
    before = 1.0 / (1.0 + a)  # the gap before each of samples 2..N
    after = a / (1.0 + a)  # the gap after each of samples 1..N-1
    weights = np.zeros(n)
    weights[0] = before[0]
    weights[1:] += before
    weights[1:-1] -= after[1:]
    total = float(weights.sum())
    return float(weights @ z / total), 1.0 / total


def median(values: list[float]) -> float:
    """``np.median(values)`` to the bit (numpy's own where a value is not finite or it is 0).

    Sorted in Python: the middle value, or the mean of the middle two as numpy takes it
    ((a + b) / 2); a burst's few dozen samples cost numpy's partition and mean more.
    """
    n = len(values)
    if n == 0 or not math.isfinite(sum(values)):  # NaN and infinities: numpy's rules
        return float(np.median(values))
    ordered = sorted(values)
    half = n // 2
    middle = ordered[half] if n % 2 else (ordered[half - 1] + ordered[half]) / 2
    if middle == 0.0:  # which of 0.0 and -0.0 is the middle one is numpy's partition's
        return float(np.median(values))
    return middle


class MoveAwareForceFilter:
    """Filter one force axis through moves and bursts; thread-safe.

    Args:
        config: axis, sign, sample period, R, the noise's cut-off, the move
            prior and the outlier gate (``ForceFilterConfig``).
    """

    def __init__(self, config: ForceFilterConfig | None = None) -> None:
        self.config = config or ForceFilterConfig()
        self._lock = threading.Lock()
        self._kf = KalmanFilter(dim_x=1, dim_z=1)
        self._kf.F = np.eye(1)
        self._kf.H = np.eye(1)
        self._kf.B = np.eye(1)
        self._variance_n2 = 0.0
        self.set_measurement_variance(self.config.measurement_variance_n2)
        self.reset()

    @property
    def measurement_variance_n2(self) -> float:
        """R: the sensor's noise variance on the axis, N^2."""
        with self._lock:
            return self._variance_n2

    @property
    def noise_correlation(self) -> float:
        """a: the noise correlation of two samples ``sample_period_s`` apart (0 = white)."""
        return self.correlation_over(self.config.sample_period_s)

    def correlation_over(self, dt_s: float) -> float:
        """The noise correlation of two samples ``dt_s`` seconds apart (0 = white)."""
        cutoff = self.config.noise_cutoff_hz
        return math.exp(-2.0 * math.pi * cutoff * dt_s) if cutoff else 0.0

    def burst_times_s(self, samples: Sequence[WrenchSample]) -> np.ndarray:
        """The burst's sample times from its first, s.

        The sensor's own time between samples (``sensor_dt_s``) where the sample tells it,
        else ``sample_period_s``.
        """
        period = self.config.sample_period_s
        steps = [period if s.sensor_dt_s is None else s.sensor_dt_s for s in samples[1:]]
        # np.concatenate(([0.0], np.cumsum(steps))): cumsum adds in order, as accumulate does
        return np.array([0.0, *itertools.accumulate(steps)], dtype=float)

    def set_measurement_variance(self, variance_n2: float) -> None:
        """Set R (N^2), the sensor's noise variance on the axis (e.g. from calibration)."""
        if not (math.isfinite(variance_n2) and variance_n2 > 0):
            raise ValueError(f"measurement variance must be > 0 N^2, got {variance_n2}")
        with self._lock:
            self._variance_n2 = float(variance_n2)

    def reset(self) -> None:
        """Forget everything: the next burst starts the filter."""
        with self._lock:
            self._kf.x = np.zeros((1, 1))
            self._kf.P = np.array([[_UNKNOWN_VAR_N2]])
            self._started = False
            self.outliers = 0

    @property
    def force_n(self) -> float:
        """The filtered force in N (nan before the first sample)."""
        with self._lock:
            return float(self._kf.x[0, 0]) if self._started else math.nan

    @property
    def force_std_n(self) -> float:
        """The filter's own standard deviation of the force, N (nan before the first sample)."""
        with self._lock:
            return math.sqrt(float(self._kf.P[0, 0])) if self._started else math.nan

    def on_move(self, expected_change_n: float = 0.0, change_std_n: float | None = None) -> None:
        """The cell moved: the force may have changed by ``expected_change_n`` ± ``change_std_n``.

        ``change_std_n`` defaults to the config's ``move_change_std_n`` (no prediction).
        """
        std = self.config.move_change_std_n if change_std_n is None else change_std_n
        if not (math.isfinite(expected_change_n) and math.isfinite(std) and std >= 0):
            raise ValueError(f"need a finite change and std >= 0, got {expected_change_n}, {std}")
        with self._lock:
            if self._started:
                self._kf.predict(u=np.array([[expected_change_n]]), Q=np.array([[std * std]]))

    def on_burst(self, samples: Sequence[WrenchSample]) -> float:
        """Filter a burst of consecutive samples taken while the cell stood still; return N."""
        config = self.config
        if len(samples) == 0:
            raise ValueError("a burst needs at least one sample")
        values = config.normal_force(np.array([s.wrench for s in samples], dtype=float))
        with self._lock:
            gate = config.jump_gate_sigma * math.sqrt(self._variance_n2)
            distance = np.abs(values - median(values.tolist()))
            keep = distance <= gate
            if not keep.any():  # a gate narrower than the samples' spacing: the middle one
                keep[int(np.argmin(distance))] = True
            self.outliers += int(len(values) - keep.sum())
            gaps_s = np.diff(self.burst_times_s(samples)[keep])
            cutoff = config.noise_cutoff_hz
            correlations = np.exp(-2.0 * math.pi * cutoff * gaps_s) if cutoff else 0.0 * gaps_s
            mean, factor = burst_mean(values[keep], correlations)
            self._kf.update(np.array([[mean]]), R=np.array([[self._variance_n2 * factor]]))
            self._started = True
            return float(self._kf.x[0, 0])

    def on_sample(self, sample: WrenchSample) -> None:
        """Filter one sample as a burst of one (a guard reading on the way)."""
        self.on_burst([sample])

    def update(self, measurement_n: float) -> float:
        """Filter one measurement (N) as a burst of one; returns the estimate."""
        values = [measurement_n]
        with self._lock:
            self._kf.update(np.array([[values[0]]]), R=np.array([[self._variance_n2]]))
            self._started = True
            return float(self._kf.x[0, 0])
