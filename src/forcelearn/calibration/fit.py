"""The fits: noise from free-space samples, the 10-parameter tool load, the 6x6 matrix check.

Pure functions over numpy arrays; the model is in :mod:`forcelearn.calibration`.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from forcelearn.calibration.drift import DriftModel, Whitener, diagonal_whitener, whitener
from forcelearn.calibration.model import (
    MM_PER_M,
    STANDARD_GRAVITY_M_S2,
    TOOL_DOWN,
    MatrixCheck,
    NoiseEstimate,
    PoseFit,
    Quaternion,
    ToolLoad,
    floats,
    gravity_in_sensor,
)
from forcelearn.errors import CalibrationError

MAX_CONDITION = 20.0
"""Largest condition number of the column-normalised design matrix that is fitted.

Tool down plus four tilts of 90 deg gives 1.3, of 45 deg 3.6, of 10 deg 18;
tool down plus two tilts of 20 deg 18, of 5 deg 76 (refused); fewer than
three distinct gravity directions, or turns about the vertical only, give
infinity (refused)."""
DEFAULT_AXIS_STD = (1.0, 1.0, 1.0, 0.1, 0.1, 0.1)
"""Row weights (N, N*m) when no measured noise is given."""


# ---- the design matrix and its conditioning ---------------------------------------------
def _skew(v: np.ndarray) -> np.ndarray:
    """Return [v]x, the matrix with [v]x u = v x u."""
    return np.array([[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]])


def design_matrix(quaternions: list[Quaternion]) -> np.ndarray:
    """Return the (6n, 10) design matrix: per pose [[g_s, 0, I, 0], [0, -[g_s]x, 0, I]]."""
    blocks = []
    for q in quaternions:
        g = gravity_in_sensor(q)
        block = np.zeros((6, 10))
        block[:3, 0] = g
        block[3:, 1:4] = -_skew(g)
        block[:3, 4:7] = np.eye(3)
        block[3:, 7:10] = np.eye(3)
        blocks.append(block)
    return np.vstack(blocks) if blocks else np.zeros((0, 10))


def design_with_drift(quaternions: list[Quaternion], times_s: np.ndarray | None = None,
                      knots_s: np.ndarray | None = None) -> np.ndarray:
    """Return the design matrix; with bias knots, the bias drifts piecewise linearly.

    Without ``knots_s`` the columns are (m, m c, F0, M0), 10. With them (K
    times, s, of the reference orientation's visits) and ``times_s`` (each
    pose's mean sample time, s, same clock), the bias is the linear
    interpolation of K values (6 each) between the knots, constant outside:
    columns (m, m c, b_1, ..., b_K), 4 + 6K.
    """
    a = design_matrix(quaternions)
    if knots_s is None or times_s is None:
        return a
    knots = np.asarray(knots_s, dtype=float)
    t = np.asarray(times_s, dtype=float)
    hats = np.array([np.interp(t, knots, e) for e in np.eye(len(knots))]).T  # (n, K)
    n, k = len(quaternions), len(knots)
    bias = np.einsum("ik,ab->iakb", hats, np.eye(6)).reshape(6 * n, 6 * k)
    return np.hstack([a[:, :4], bias])


def condition_number(quaternions: list[Quaternion], times_s: np.ndarray | None = None,
                     knots_s: np.ndarray | None = None) -> float:
    """Return the condition number of the column-normalised design matrix (inf if singular)."""
    if len(quaternions) < 2:
        return math.inf
    a = design_with_drift(quaternions, times_s, knots_s)
    norms = np.linalg.norm(a, axis=0)
    if np.any(norms <= 1e-12 * norms.max()):  # a parameter no pose excites
        return math.inf
    a = a / norms
    singular = np.linalg.svd(a, compute_uv=False)
    return math.inf if singular[-1] <= 1e-12 * singular[0] else float(singular[0] / singular[-1])


def orientation_with_down(axis_sensor: np.ndarray) -> Quaternion:
    """Return an orientation in which the sensor-frame direction ``axis_sensor`` points down.

    Tool-down followed by the shortest turn, in the sensor frame, that takes
    ``axis_sensor`` to sensor +z (the orientation closest to tool-down).
    """
    d = np.asarray(axis_sensor, dtype=float) / np.linalg.norm(axis_sensor)
    dot = float(d[2])
    if dot < -1 + 1e-9:  # straight up: half turn about sensor x
        turn = np.array([0.0, 1.0, 0.0, 0.0])
    else:
        turn = np.array([1.0 + dot, *np.cross(d, (0.0, 0.0, 1.0))])
        turn /= np.linalg.norm(turn)
    w1, x1, y1, z1 = TOOL_DOWN
    w2, x2, y2, z2 = turn
    q = np.array([  # Hamilton product TOOL_DOWN * turn
        w1 * w2 - x1 * x2 - y1 * y2 - z1 * z2,
        w1 * x2 + x1 * w2 + y1 * z2 - z1 * y2,
        w1 * y2 - x1 * z2 + y1 * w2 + z1 * x2,
        w1 * z2 + x1 * y2 - y1 * x2 + z1 * w2,
    ])
    return floats(q / np.linalg.norm(q))  # type: ignore[return-value]


CANDIDATES: tuple[tuple[str, tuple[float, float, float]], ...] = (
    ("tool down (sensor +z down)", (0.0, 0.0, 1.0)),
    ("tool horizontal, sensor +x down", (1.0, 0.0, 0.0)),
    ("tool horizontal, sensor -x down", (-1.0, 0.0, 0.0)),
    ("tool horizontal, sensor +y down", (0.0, 1.0, 0.0)),
    ("tool horizontal, sensor -y down", (0.0, -1.0, 0.0)),
    ("tool tilted 45 deg, sensor +x+z down", (1.0, 0.0, 1.0)),
    ("tool tilted 45 deg, sensor -x+z down", (-1.0, 0.0, 1.0)),
    ("tool tilted 45 deg, sensor +y+z down", (0.0, 1.0, 1.0)),
    ("tool tilted 45 deg, sensor -y+z down", (0.0, -1.0, 1.0)),
)
"""Orientations offered when a pose set is ill-conditioned (none points the tool up)."""


def _information(quaternions: list[Quaternion]) -> float:
    """Return log det of the information matrix (columns at unit scale): larger is better."""
    a = design_matrix(quaternions)
    a[:, :4] /= STANDARD_GRAVITY_M_S2
    singular = np.linalg.svd(a, compute_uv=False)
    return float(np.sum(np.log(singular**2 + 1e-6)))


def suggest_poses(quaternions: list[Quaternion], limit: float = MAX_CONDITION,
                  most: int = 4) -> list[tuple[str, Quaternion]]:
    """Return up to ``most`` candidate orientations that, added in turn, get under ``limit``.

    Each is the candidate adding the most information (D-optimal: largest
    log-determinant), which also works while the set is still singular.
    """
    options = [(name, orientation_with_down(np.array(axis))) for name, axis in CANDIDATES]
    chosen: list[tuple[str, Quaternion]] = []
    current = list(quaternions)
    while len(chosen) < most and condition_number(current) > limit:
        name, q = max(options, key=lambda option: _information([*current, option[1]]))
        chosen.append((name, q))
        current.append(q)
    return chosen


def check_pose_set(quaternions: list[Quaternion], limit: float = MAX_CONDITION) -> float:
    """Return the condition number; raise CalibrationError naming orientations to add."""
    cond = condition_number(quaternions)
    if cond <= limit:
        return cond
    adds = "; ".join(
        f"{name} = quaternion [{', '.join(f'{c:.4f}' for c in q)}]"
        for name, q in suggest_poses(quaternions, limit)
    )
    raise CalibrationError(
        f"ill-conditioned pose set: {len(quaternions)} orientation(s), condition number "
        f"{cond:.3g} > {limit:g}, so mass, centre of mass and bias cannot be told apart; "
        f"add orientations whose gravity directions differ by 45 to 90 deg, e.g. {adds}"
    )


# ---- fits -------------------------------------------------------------------------------
def estimate_noise(wrenches: np.ndarray, timestamps_s: np.ndarray,
                   zero_quaternion: Quaternion = TOOL_DOWN) -> NoiseEstimate:
    """Estimate residual bias (the mean), drift (linear trend) and 6x6 noise covariance."""
    w = np.asarray(wrenches, dtype=float)
    t = np.asarray(timestamps_s, dtype=float)
    if w.ndim != 2 or w.shape[1] != 6 or len(w) < 10 or t.shape != (len(w),):
        raise ValueError(f"need at least 10 samples of 6 axes with timestamps, got {w.shape}")
    duration = float(t[-1] - t[0])
    centred_t = t - t.mean()
    spread = float(centred_t @ centred_t)
    centred_w = w - w.mean(axis=0)
    slope = (centred_t @ centred_w) / spread if spread > 0 else np.zeros(6)
    detrended = centred_w - np.outer(centred_t, slope)
    covariance = detrended.T @ detrended / (len(w) - 2)
    return NoiseEstimate(
        bias=floats(w.mean(axis=0)),
        covariance=tuple(floats(row) for row in covariance),
        drift_per_s=floats(slope),
        samples=len(w),
        duration_s=duration,
        rate_hz=(len(w) - 1) / duration if duration > 0 else 0.0,
        zero_quaternion=floats(zero_quaternion),  # type: ignore[arg-type]
    )


def fit_tool_load(
    quaternions: list[Quaternion],
    means: np.ndarray,
    axis_std: np.ndarray | tuple[float, ...] = DEFAULT_AXIS_STD,
    names: list[str] | None = None,
    samples: list[int] | None = None,
    limit: float = MAX_CONDITION,
    times_s: np.ndarray | None = None,
    knots_s: np.ndarray | None = None,
    drift: DriftModel | None = None,
) -> ToolLoad:
    """Fit mass, centre of mass and bias to the mean readings (n, 6) at ``quaternions``.

    Rows are weighted by ``1 / axis_std`` (N, N*m: the measured noise), so forces
    and moments count alike; uncertainties are ``s^2 (A^T A)^-1`` on the weighted
    rows, ``s^2`` the residual variance. With ``times_s`` (each pose's mean sample
    time, s) and ``knots_s`` (:func:`bias_knots`) the bias drifts piecewise
    linearly between the knots; F0, M0 are then the first knot's. With ``drift``
    (and ``times_s``) the rows are whitened by the noise of each pose mean and the
    bias's random walk about that fit (:mod:`.drift`, generalised least squares), and
    the covariance is ``max(s^2, 1) (A^T W^T W A)^-1``: never tighter than that model. Raises
    CalibrationError when the set is ill-conditioned or the mass comes out
    non-positive.
    """
    means = np.asarray(means, dtype=float)
    if means.shape != (len(quaternions), 6):
        raise ValueError(f"means must be ({len(quaternions)}, 6), got {means.shape}")
    cond = check_pose_set(quaternions, limit)
    if knots_s is not None:
        cond = max(cond, condition_number(quaternions, times_s, knots_s))
    a, y = design_with_drift(quaternions, times_s, knots_s), means.ravel()
    white = row_whitener(len(quaternions), axis_std, times_s, knots_s, drift)
    aw, yw = white @ a, white @ y
    p, *_ = np.linalg.lstsq(aw, yw, rcond=None)
    dof = len(yw) - a.shape[1]
    s2 = float(np.sum((yw - aw @ p) ** 2) / dof) if dof > 0 else math.nan
    cov = (max(s2, 1.0) if drift is not None else s2) * np.linalg.inv(aw.T @ aw)
    mass, mc = float(p[0]), p[1:4]
    if not mass > 0:
        raise CalibrationError(
            f"fitted tool mass {mass:.4f} kg is not positive: check the robot's quaternion "
            "convention (w, x, y, z; sensor frame to world, world z up) and the sensor mounting"
        )
    jac = np.hstack([-mc[:, None] / mass**2, np.eye(3) / mass])  # d(mc/m) / d(m, mc)
    com_cov = jac @ cov[:4, :4] @ jac.T
    residuals = (y - a @ p).reshape(-1, 6)
    names = names or [f"pose {i + 1}" for i in range(len(quaternions))]
    counts = samples or [0] * len(quaternions)
    std_p = np.sqrt(np.diag(cov))
    return ToolLoad(
        mass_kg=mass,
        mass_std_kg=float(std_p[0]),
        com_mm=floats(mc / mass * MM_PER_M),
        com_std_mm=floats(np.sqrt(np.diag(com_cov)) * MM_PER_M),
        force_bias_n=floats(p[4:7]),
        force_bias_std_n=floats(std_p[4:7]),
        torque_bias_nm=floats(p[7:10]),
        torque_bias_std_nm=floats(std_p[7:10]),
        **drift_fields(p, cov, knots_s),
        condition_number=cond,
        poses=tuple(
            PoseFit(names[i], floats(q), int(counts[i]), floats(means[i]),  # type: ignore[arg-type]
                    floats(residuals[i]))
            for i, q in enumerate(quaternions)
        ),
    )


def row_whitener(count: int, axis_std: np.ndarray | tuple[float, ...],
                 times_s: np.ndarray | None, knots_s: np.ndarray | None,
                 drift: DriftModel | None) -> Whitener:
    """W (6n rows): 1 / axis_std per row, or with ``drift`` the GLS whitener of :mod:`.drift`."""
    if drift is None or times_s is None:
        return diagonal_whitener(count, np.asarray(axis_std, dtype=float))
    return whitener(np.asarray(times_s, dtype=float), knots_s, drift)


REVISIT_DEG = 1.0
"""A pose within this angle (deg) of the first is a visit to the reference orientation."""


def bias_knots(quaternions: list[Quaternion], times_s: np.ndarray | None,
               limit: float = MAX_CONDITION) -> np.ndarray | None:
    """Return the times (s) of the visits to the first orientation, if they determine a drift.

    They do when it was visited at least twice at distinct times (what changes
    there is the bias alone) and the design with the drift stays under
    ``limit``; else None: the bias is fitted constant. Without a revisit a
    drift would be told apart from the tool's load only by the order of the
    poses, which is not honest.
    """
    if times_s is None or len(quaternions) < 3:
        return None
    t = np.asarray(times_s, dtype=float)
    q = np.asarray(quaternions, dtype=float)
    cos_limit = math.cos(math.radians(REVISIT_DEG) / 2)
    knots = np.array(sorted({float(t[i]) for i in range(len(q))
                             if abs(float(q[i] @ q[0])) >= cos_limit}))
    if len(knots) < 2 or not np.all(np.isfinite(knots)):
        return None
    if math.isfinite(limit) and condition_number(quaternions, t, knots) > limit:
        return None
    return knots


def drift_fields(p: np.ndarray, cov: np.ndarray, knots_s: np.ndarray | None) -> dict[str, Any]:
    """``ToolLoad`` drift fields: the mean drift rate, last knot less first over their time."""
    if knots_s is None:
        return {}
    k, span = len(knots_s), float(knots_s[-1] - knots_s[0])
    first, last = slice(4, 10), slice(4 + 6 * (k - 1), 10 + 6 * (k - 1))
    rate = (p[last] - p[first]) / span
    var = (np.diag(cov[last, last]) + np.diag(cov[first, first])
           - 2 * np.diag(cov[last, first])) / span**2
    return {"bias_drift_per_s": floats(rate),
            "bias_drift_std_per_s": floats(np.sqrt(np.maximum(var, 0.0)))}


def check_matrix(raw: np.ndarray, applied: np.ndarray) -> MatrixCheck:
    """Fit W = R C^T over known loads (at least 12 rows of 6) and report per-axis residuals."""
    r, w = np.asarray(raw, dtype=float), np.asarray(applied, dtype=float)
    if r.shape != w.shape or r.ndim != 2 or r.shape[1] != 6:
        raise ValueError(f"raw and applied must both be (n, 6), got {r.shape} and {w.shape}")
    if len(r) < 12:
        raise CalibrationError(
            f"the loads check needs at least 12 loads (two per axis), the CSV has {len(r)}"
        )
    if np.linalg.matrix_rank(r) < 6:
        raise CalibrationError(
            "the loads do not excite all six axes (raw readings have rank < 6): add loads "
            "along each force axis and moments about each axis"
        )
    ct, *_ = np.linalg.lstsq(r, w, rcond=None)
    return MatrixCheck(
        loads=len(r),
        matrix=tuple(floats(row) for row in ct.T),
        rms_residual_fit=floats(np.sqrt(np.sum((w - r @ ct) ** 2, axis=0) / (len(r) - 6))),
        rms_residual_sensor=floats(np.sqrt(np.mean((w - r) ** 2, axis=0))),
    )
