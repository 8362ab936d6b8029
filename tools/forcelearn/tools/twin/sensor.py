"""The sensor's part of the twin: noise, its colour, and bias drift, from bursts and tares.

* noise: the pooled variance of the bursts' samples about their means, less the fitted
  model's own force variance within each burst (a foam still relaxing after a step, the
  lag's last approach: :func:`~forcelearn.tools.twin.forward.within_burst_variance`;
  counted as noise it put relaxing hidden cells' noise 2-10 % high), each burst's
  share corrected for its own length (``n`` samples of an AR(1) noise ``phi`` keep
  ``1 - mean_share(phi, n)`` of the variance about their mean, about ``1 - g / n`` with
  ``g = (1 + phi) / (1 - phi)``; corrected at the bursts' mean length instead, the short
  control-step bursts beside the probe's long ones read 2.5 % low on a coloured cell). Its
  1-sigma is the largest of the sampling one (chi-square over the samples' effective count)
  and half the gap between the control steps' bursts and the others (the probe's, the
  approach reads), and between the free-space bursts and those in contact: an estimate
  that depends on which bursts gave it (a force still relaxing within a burst reads as
  noise; in free space nothing moves but the sensor) is not known better than that;
* colour: the AR(1) coefficient ``phi`` per sample that makes the burst means
  scatter as much as the fit's residuals do (``var(mean) = g sigma^2 / n``): an
  upper bound, since the residuals also hold what the model misses;
* bias drift: each accepted tare's reading is the bias's random walk since the
  previous zeroing, ``var = D^2 dt``; without tares the free-space reads of
  successive trials measure it (:mod:`forcelearn.tools.twin.bias`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from forcelearn.records import BurstRecord, TrialRecords
from forcelearn.tools.twin.arrays import RecordArrays


@dataclass(frozen=True)
class SensorFit:
    """Noise (N per sample), colour (AR(1) per sample), drift (N/sqrt(s)), 1-sigma each."""

    noise_n: float
    noise_sigma_n: float
    colour_phi: float
    """Upper bound of the AR(1) coefficient per sample (NaN: not measurable)."""
    drift_n_per_sqrt_s: float
    drift_sigma: float
    tares: int
    samples: int
    drift_source: str = "tares"
    """What measured the drift: "tares", "free-space reads" (:mod:`.bias`) or "none"."""
    drift_allowed: float = math.nan
    """The largest rate the tares allow at 1 sigma, N/sqrt(s) (NaN: not measured): the
    walk an identification's bias follows when the drift is not told from 0 (:mod:`.bias`)."""


def _colour_gain(phi: float) -> float:
    return (1 + phi) / (1 - phi) if phi < 1 else math.inf


def mean_share(phi: float, n: float) -> float:
    """Var(mean of n AR(1) samples) / sigma^2, exact for a whole n."""
    count = max(1, round(n))
    lags = np.arange(1, count)
    return float((count + 2 * np.sum((count - lags) * phi**lags)) / count**2)


SPLIT_MIN_BURSTS = 10
"""Bursts each side needs for the control steps' and the other bursts' noise to be compared."""


def _pooled_noise(data: RecordArrays, mask: np.ndarray, phi: float,
                  signal: np.ndarray | None = None) -> float:
    """The noise (N per sample) from the bursts ``mask`` picks (NaN: none).

    Each burst's ``n`` samples about their mean keep ``n (1 - mean_share(phi, n))`` of the
    variance (``std_n`` is ddof 0): the summed squares over their expectation, less the
    modelled force's own variance within each burst (``signal``, (T, M) N^2; None: none).
    """
    if not mask.any():
        return math.nan
    counts = data.count[mask].astype(float)
    lengths, inverse = np.unique(np.round(counts), return_inverse=True)
    kept = np.array([max(0.05, 1 - mean_share(phi, float(n))) for n in lengths])[inverse]
    squares = data.std_n[mask] ** 2
    if signal is not None:
        squares = squares - np.nan_to_num(signal[mask])
    return math.sqrt(max(0.0, float(np.sum(counts * squares) / np.sum(counts * kept))))


def fit_sensor(records: list[TrialRecords], data: RecordArrays,
               residuals: np.ndarray | None, calibration_noise_n: float | None,
               configured_phi: float | None = None,
               signal: np.ndarray | None = None) -> SensorFit:
    """Estimate the sensor's noise, colour and drift; ``residuals`` are the fit's (T, M).

    The within-burst correction uses ``configured_phi`` (the colour the run's sensor
    settings give) when known, else none (white noise: the noise then reads low by
    the share of its variance the burst mean holds). ``signal`` (T, M), N^2: the fitted
    model's force's own variance within each burst
    (:func:`~forcelearn.tools.twin.forward.within_burst_variance`), not the sensor's.
    """
    many = data.has_burst & (data.count > 1)
    counts = data.count[many]
    var_in_burst = float(np.mean(data.std_n[many] ** 2)) if many.any() else math.nan
    phi = math.nan
    if residuals is not None and many.any() and var_in_burst > 0:
        use = many & np.isfinite(residuals)
        expected = var_in_burst * np.mean(1.0 / data.count[use])
        ratio = float(np.mean(residuals[use] ** 2) / expected) if expected > 0 else math.nan
        if math.isfinite(ratio):
            phi = min(0.999, max(0.0, (ratio - 1) / (ratio + 1)))
    n_mean = float(np.mean(counts)) if counts.size else 1.0
    colour = configured_phi if configured_phi is not None else 0.0
    gain = _colour_gain(colour)
    noise = _pooled_noise(data, many, colour, signal)
    effective = float(np.sum(counts - 1)) / max(gain, 1.0) if counts.size else 0.0
    noise_sigma = noise / math.sqrt(2 * effective) if effective > 0 else math.inf
    touching = many & (data.mean_n > max(0.5, 3.0 * noise))
    for part in (many & data.is_step, many & ~touching):  # vs the rest: steps, free space
        rest = many & ~part
        if part.sum() >= SPLIT_MIN_BURSTS and rest.sum() >= SPLIT_MIN_BURSTS:
            gap = abs(_pooled_noise(data, part, colour, signal)
                      - _pooled_noise(data, rest, colour, signal))
            noise_sigma = max(noise_sigma, 0.5 * gap)
    if calibration_noise_n is not None:
        noise, noise_sigma = calibration_noise_n, 0.0
    drift, drift_sigma, tares, allowed = _drift(records, noise, n_mean, colour)
    return SensorFit(noise, noise_sigma, phi, drift, drift_sigma, tares,
                     int(np.sum(counts)) if counts.size else 0, drift_allowed=allowed)


DRIFT_OUTLIER_SIGMAS = 5.0
"""A tare reading beyond this many of its expected spreads is no step of the walk (a re-zero
after a fault reads the sensor's raw bias): it is left out of the drift's estimate."""


@dataclass(frozen=True)
class TareRead:
    """One accepted tare: what it read before zeroing."""

    trial: int
    time_s: float
    """Cell time, s."""
    mean_n: float
    """The mean of the burst it zeroed on (else its recorded reading), N."""
    count: int
    """That burst's samples (0: not in the records)."""
    rank: int
    """Which of the trial's bursts recorded at ``time_s`` it read (0: the first; -1: none)."""


def tare_reads(records: list[TrialRecords]) -> list[TareRead]:
    """The accepted tares in record order (trial, then time).

    A tare reads a burst and then zeroes (a zero check in software on that burst's mean).
    The cell's clock does not run during a read, so several bursts of a trial may carry
    the tare's time (a probe point's zero check, then its two free-space reads, all at the
    time the move there settled): the tare's is the one whose filtered force is the tare's
    reading (the same number), else the first. Its mean is the reading (the tare's own
    ``reading_n`` is the force filter's estimate, not what was zeroed); a tare without a
    burst at its time keeps ``reading_n``, a count of 0 and rank -1.
    """
    out = []
    for trial in records:
        at: dict[float, list[BurstRecord]] = {}
        for step in trial.steps:
            if step.burst is not None:
                at.setdefault(step.move.settled_s, []).append(step.burst)
        for tare in trial.tares:
            if not (tare.accepted and math.isfinite(tare.time_s)):
                continue
            bursts = at.get(tare.time_s, [])
            rank = next((k for k, b in enumerate(bursts) if b.filtered_n == tare.reading_n),
                        0 if bursts else -1)
            if rank < 0:
                out.append(TareRead(trial.trial, tare.time_s, tare.reading_n, 0, -1))
            else:
                burst = bursts[rank]
                out.append(TareRead(trial.trial, tare.time_s, burst.mean_n, burst.count, rank))
    return sorted(out, key=lambda r: (r.trial, r.time_s, r.rank))


def zero_variance(noise_n: float, phi: float, count: float) -> float:
    """Variance of a zero taken on a burst of ``count`` samples (its mean's error), N^2."""
    if not math.isfinite(noise_n) or count < 1:
        return 0.0
    return noise_n**2 * mean_share(phi, count)


def _drift(records: list[TrialRecords], noise_n: float, n_mean: float,
           phi: float) -> tuple[float, float, int, float]:
    """The bias's random-walk rate from successive accepted tares (NaN, inf: none).

    Returns the rate, its 1-sigma, the tares, and the largest rate they allow at 1 sigma
    (``sqrt(D^2 + sd(D^2))``, also where the estimate of ``D^2`` is 0 and its 1-sigma
    on ``D`` is infinite).

    Each tare zeroes on the burst it read, so the next one reads the walk since then plus
    both bursts' errors: ``r_k = w_k + e_k - e_(k-1)``, ``var(r_k) = D^2 dt_k + s_k^2 +
    s_(k-1)^2``, and successive readings share ``-s_k^2``. Counting one read's error only
    put the default cell's 0.02 N/sqrt(s) at 0.025-0.029 +- 0.0011 over 300 trials (the
    §5 run's zero check at every trial's end is a tare; 25-sample bursts, 0.0041 N^2 each,
    against 0.0068 N^2 of walk per trial). The 1-sigma is the moment estimate's own (those
    variances and covariances), not a pure walk's ``D / sqrt(2 n)``.
    """
    reads = tare_reads(records)
    if len(reads) < 3:
        return math.nan, math.inf, len(reads), math.nan
    times = np.array([r.time_s for r in reads])
    values = np.array([r.mean_n for r in reads[1:]])
    zero_var = np.array([zero_variance(noise_n, phi, r.count if r.count > 0 else n_mean)
                         for r in reads])
    gaps = np.diff(times)
    read_var = zero_var[1:] + zero_var[:-1]
    keep = gaps > 0
    rate_sq = 0.0
    for _ in range(2):  # once, then without the readings beyond the walk's spread
        if not keep.any():
            return math.nan, math.inf, len(reads), math.nan
        rate_sq = max(0.0, float(np.sum(values[keep] ** 2 - read_var[keep]) / np.sum(gaps[keep])))
        spread = np.sqrt(rate_sq * gaps + read_var)
        keep = (gaps > 0) & (np.abs(values) <= DRIFT_OUTLIER_SIGMAS * np.maximum(spread, 1e-12))
    rate = math.sqrt(rate_sq)
    variance = rate_sq * gaps + read_var
    shared = np.where(keep[1:] & keep[:-1], zero_var[1:-1], 0.0)  # cov(r_k, r_k+1) = -s_k^2
    var_sum = float(np.sum(2 * variance[keep] ** 2) + np.sum(4 * shared**2))
    sd_rate_sq = math.sqrt(var_sum) / float(np.sum(gaps[keep]))
    allowed = math.sqrt(rate_sq + sd_rate_sq)
    if not rate > 0:
        return rate, math.inf, len(reads), allowed
    return rate, sd_rate_sq / (2 * rate), len(reads), allowed
