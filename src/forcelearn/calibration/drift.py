"""The bias drift as a random walk: generalised least squares and the predicted precision.

The sensor's bias is a random walk (variance ``q`` per s on each axis, N^2/s or
(N*m)^2/s) on top of white noise. The fit (:func:`~.fit.design_with_drift`)
takes the bias as piecewise linear between the knots, the visits to the first
orientation; what the random walk adds between two knots ``k < t, t' < k + T``
is a Brownian bridge, and outside the knots a walk from the nearest one::

    cov(e(t), e(t'))  = q (min(s, s') - s s' / T)     s = t - k, same interval
                      = q min(|t - k|, |t' - k|)      same side of the same end knot
                      = 0                             otherwise

plus each pose mean's own variance ``v_i`` (its noise, from the blocks of its
read) on the diagonal. Without knots the walk starts at the first pose. The
fit whitens rows and design by ``L^-1`` (``L L^T`` that covariance, per axis):
generalised least squares, whose ``(A^T W^T W A)^-1`` is the covariance of the
parameters, predictable from the design alone before the poses are measured
(:func:`predicted_com_std_mm`): what :mod:`forcelearn.tools.commands.calibrate_precision`
uses to decide how many cycles of the orientations a tool needs.

``q`` comes from the data: consecutive visits to the first orientation differ
by the walk alone, ``E[dy^2] = q dt + v_i + v_j``, pooled over the force axes
and over the moment axes (:func:`drift_variance`).
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass

import numpy as np
import scipy.linalg

from forcelearn.calibration.model import MM_PER_M, Quaternion

COM_TOLERANCE_MM = 1.0
"""The centre of mass's tolerance: this many mm ...."""
COM_TOLERANCE_FRACTION = 0.005
"""... plus this fraction of its distance from the sensor origin."""
TARGET_FRACTION = 1.0 / 3.0
"""The predicted sigma of the centre of mass aimed at, as a fraction of its tolerance."""


@dataclass(frozen=True)
class DriftModel:
    """The noise of each pose mean (n, 6) and the bias walk's variance rate (6,)."""

    mean_var: np.ndarray
    """Variance of each pose's mean reading (N^2, (N*m)^2), (n, 6)."""
    walk_var_per_s: np.ndarray
    """Random-walk variance rate of the bias per axis (N^2/s, (N*m)^2/s), (6,)."""


def com_tolerance_mm(com_mm: np.ndarray | tuple[float, ...]) -> float:
    """The issue's bound on the centre of mass's error: 1 mm + 0.5 % of its distance (mm)."""
    return COM_TOLERANCE_MM + COM_TOLERANCE_FRACTION * float(np.linalg.norm(com_mm))


def _walk_covariance(times: np.ndarray, knots: np.ndarray | None) -> np.ndarray:
    """Covariance (n, n) of the bias's departure from the fitted one, per unit variance rate."""
    t = np.asarray(times, dtype=float)
    if knots is None or len(knots) < 2:
        s = t - t[0]
        out: np.ndarray = np.minimum.outer(np.maximum(s, 0.0), np.maximum(s, 0.0))
        return out
    k = np.asarray(knots, dtype=float)
    # segment -1 before the first knot, len(k) - 1 after the last, else the interval index
    segment = np.searchsorted(k, t, side="right") - 1
    segment[t >= k[-1]] = len(k) - 1
    inner = np.clip(segment, 0, len(k) - 2)
    start = np.where(segment < 0, k[0], np.where(segment == len(k) - 1, k[-1], k[inner]))
    s = np.abs(t - start)  # time from the knot the walk or bridge starts at
    span = np.where((segment >= 0) & (segment < len(k) - 1), k[inner + 1] - k[inner], np.inf)
    cov: np.ndarray = np.minimum.outer(s, s) - np.outer(s, s) / span[:, None]
    cov[segment[:, None] != segment[None, :]] = 0.0
    return cov


class Whitener:
    """Per-axis inverse Cholesky factors (6, n, n); ``W @ m`` whitens pose-major rows (6n, ...)."""

    def __init__(self, factors: np.ndarray) -> None:
        self.factors = factors

    def __matmul__(self, m: np.ndarray) -> np.ndarray:
        m = np.asarray(m, dtype=float)
        out = np.zeros(m.shape)
        for axis in range(6):
            rows = m[axis::6]
            if rows.ndim == 1:
                out[axis::6] = self.factors[axis] @ rows
                continue
            used = np.any(rows != 0.0, axis=0)  # a design's other axes' bias columns are zero
            out[axis::6, used] = self.factors[axis] @ rows[:, used]
        return out


def whitener(times_s: np.ndarray, knots_s: np.ndarray | None, model: DriftModel) -> Whitener:
    """Return W with W^T W the inverse covariance of the pose-major rows (6n)."""
    walk = _walk_covariance(times_s, knots_s)
    n = len(times_s)
    factors = np.empty((6, n, n))
    for axis in range(6):
        cov = model.walk_var_per_s[axis] * walk + np.diag(model.mean_var[:, axis])
        chol = np.linalg.cholesky(cov + 1e-15 * np.trace(cov) / n * np.eye(n))
        factors[axis] = scipy.linalg.solve_triangular(chol, np.eye(n), lower=True)
    return Whitener(factors)


def diagonal_whitener(count: int, axis_std: np.ndarray) -> Whitener:
    """W of rows weighted by ``1 / axis_std`` (6,), ``count`` poses."""
    return Whitener(np.array([np.eye(count) / float(s) for s in axis_std]))


def drift_variance(quaternions: list[Quaternion], times_s: np.ndarray, means: np.ndarray,
                   mean_var: np.ndarray, revisit_cos: float) -> np.ndarray:
    """Random-walk variance rate (6,) from consecutive visits to the first orientation.

    Pooled over Fx..Fz and over Mx..Mz; zero when fewer than two visits or the
    differences are no larger than the noise.
    """
    q = np.asarray(quaternions, dtype=float)
    visits = [i for i in range(len(q)) if abs(float(q[i] @ q[0])) >= revisit_cos]
    rate = np.zeros(6)
    if len(visits) < 2:
        return rate
    t, y, v = np.asarray(times_s, dtype=float), np.asarray(means), np.asarray(mean_var)
    pairs = list(itertools.pairwise(visits))
    span = sum(float(t[j] - t[i]) for i, j in pairs)
    if not span > 0:
        return rate
    for group in (slice(0, 3), slice(3, 6)):
        excess = sum(float(np.sum((y[j, group] - y[i, group]) ** 2 - v[i, group] - v[j, group]))
                     for i, j in pairs)
        rate[group] = max(excess, 0.0) / (3 * span)
    return rate


def com_std_mm(cov: np.ndarray, mass_kg: float, mc_kgm: np.ndarray) -> float:
    """RMS of the centre of mass's error norm (mm) from the covariance of (m, m c, ...)."""
    jac = np.hstack([-np.asarray(mc_kgm)[:, None] / mass_kg**2, np.eye(3) / mass_kg])
    return float(np.sqrt(max(float(np.trace(jac @ cov[:4, :4] @ jac.T)), 0.0))) * MM_PER_M


def leading_covariance(design: np.ndarray, white: Whitener, count: int) -> np.ndarray:
    """The first ``count`` parameters' block of the GLS covariance (A^T W^T W A)^-1, (count, count).

    A Cholesky solve for those columns only (the normal matrix of a long plan has
    hundreds of bias columns: its full pseudo-inverse is the prediction's cost);
    a normal matrix that is not positive definite falls back to the pseudo-inverse.
    """
    aw = white @ design
    normal = aw.T @ aw
    try:
        factor = scipy.linalg.cho_factor(normal)
    except np.linalg.LinAlgError:
        block: np.ndarray = np.linalg.pinv(normal)[:count, :count]
        return block
    unit = np.eye(normal.shape[0], count)
    out: np.ndarray = scipy.linalg.cho_solve(factor, unit)[:count]
    return out


def predicted_com_std_mm(design: np.ndarray, white: Whitener, mass_kg: float,
                         mc_kgm: np.ndarray) -> float:
    """The RMS error norm of the centre of mass (mm) that a design would give (GLS)."""
    return com_std_mm(leading_covariance(design, white, 4), mass_kg, mc_kgm)


__all__ = [
    "COM_TOLERANCE_FRACTION",
    "COM_TOLERANCE_MM",
    "TARGET_FRACTION",
    "DriftModel",
    "Whitener",
    "com_std_mm",
    "com_tolerance_mm",
    "drift_variance",
    "leading_covariance",
    "predicted_com_std_mm",
    "whitener",
]
