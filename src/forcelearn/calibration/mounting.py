"""The tool-load fit with the sensor's mounting on the flange: given, or estimated with the tool.

The robot reports the flange's orientation ``R_f``; the sensor frame is the
flange frame turned by the mounting ``R_m``, so gravity in the sensor frame is
``g_s = R_m^T R_f^T (0, 0, -g)``. Given ``R_m`` (the operator's drawing), the
10-parameter linear fit of :func:`~forcelearn.calibration.fit.fit_tool_load`
runs on ``R_f R_m`` unchanged. Estimated, three more unknowns join it:

1. Forces alone: ``F_i = F0 + A g_f,i`` with ``A = m R_m^T`` (3x3) is linear in
   ``A`` and ``F0``; least squares, then the rotation nearest ``A`` (SVD,
   determinant +1) is the first estimate of ``R_m^T``.
2. All six axes, 13 parameters (a small rotation ``delta`` on that estimate,
   then ``m, m c, F0, M0``; 6 more per bias knot), weighted (or whitened, with
   the drift model) as the linear fit: :func:`scipy.optimize.least_squares`
   over ``delta`` alone, the rest solved linearly for each ``delta`` (variable
   projection); the covariance ``s^2 (J^T J)^-1`` of the whole model gives
   every parameter's uncertainty, the mounting's as the RMS angle.

Why estimate by default: the sensor's clocking on its adapter plate is often
not what the drawing says (a bolt circle of 6 or 8 holes allows 45 or 60 deg
steps), and a wrong mounting turns the whole compensation; the estimate costs
no extra pose and is known to a fraction of a degree with the default plan.
"""

from __future__ import annotations

import math
from dataclasses import replace
from typing import Any

import numpy as np
from scipy.optimize import least_squares
from scipy.spatial.transform import Rotation

from forcelearn.calibration.drift import DriftModel
from forcelearn.calibration.fit import (
    DEFAULT_AXIS_STD,
    MAX_CONDITION,
    bias_knots,
    check_pose_set,
    design_matrix,
    design_with_drift,
    drift_fields,
    fit_tool_load,
    row_whitener,
)
from forcelearn.calibration.model import (
    MM_PER_M,
    MOUNTING_ESTIMATED,
    MOUNTING_GIVEN,
    STANDARD_GRAVITY_M_S2,
    PoseFit,
    Quaternion,
    ToolLoad,
    floats,
    sensor_quaternion,
)
from forcelearn.devices import quaternion_to_matrix

GRAVITY_WORLD = np.array([0.0, 0.0, -STANDARD_GRAVITY_M_S2])


def _quaternion(rotation: Rotation) -> Quaternion:
    x, y, z, w = rotation.as_quat()
    q = (float(w), float(x), float(y), float(z))
    return q if q[0] >= 0 else (-q[0], -q[1], -q[2], -q[3])


def initial_mounting(flange: list[Quaternion], means: np.ndarray) -> Quaternion:
    """First estimate of R_m from the forces alone (linear in m R_m^T and F0, then SVD)."""
    g_f = np.array([quaternion_to_matrix(q).T @ GRAVITY_WORLD for q in flange])  # (n, 3)
    rows = np.hstack([g_f, np.ones((len(flange), 1))])  # F_i^T = g_f,i^T A^T + F0^T
    solution, *_ = np.linalg.lstsq(rows, np.asarray(means)[:, :3], rcond=None)
    a = solution[:3].T  # A = m R_m^T
    u, _, vt = np.linalg.svd(a)
    r_mt = u @ np.diag([1.0, 1.0, float(np.sign(np.linalg.det(u @ vt)))]) @ vt
    return _quaternion(Rotation.from_matrix(r_mt.T))


def fit_with_mounting(
    flange: list[Quaternion],
    means: np.ndarray,
    axis_std: np.ndarray | tuple[float, ...] = DEFAULT_AXIS_STD,
    names: list[str] | None = None,
    samples: list[int] | None = None,
    limit: float = MAX_CONDITION,
    mounting: Quaternion | None = None,
    times_s: np.ndarray | None = None,
    drift: DriftModel | None = None,
) -> ToolLoad:
    """Fit the tool load at the robot's (flange) orientations; the mounting given or estimated.

    ``times_s``: each pose's mean sample time (s); the bias is fitted as drifting
    piecewise linearly between the visits to the first orientation when
    :func:`~forcelearn.calibration.fit.bias_knots` finds they determine it,
    else constant; with ``drift`` by generalised least squares (:mod:`.drift`). Raises
    CalibrationError when the pose set is ill-conditioned (checked in the
    sensor frame, before any fit) or the mass comes out non-positive.
    """
    means = np.asarray(means, dtype=float)
    knots = bias_knots(list(flange), times_s, limit)
    if mounting is not None:
        load = fit_tool_load([sensor_quaternion(q, mounting) for q in flange], means, axis_std,
                             names, samples, limit, times_s, knots, drift)
        return _in_flange_frame(load, flange, mounting, 0.0, MOUNTING_GIVEN)
    check_pose_set(list(flange), limit)  # conditioning does not depend on a fixed rotation
    start = Rotation.from_quat(_xyzw(initial_mounting(flange, means)))
    white = row_whitener(len(flange), axis_std, times_s, knots, drift)
    y = white @ means.ravel()
    bias_columns = white @ design_with_drift(list(flange), times_s, knots)[:, 4:]

    def load_columns(x: np.ndarray) -> np.ndarray:
        r_m = _quaternion(start * Rotation.from_rotvec(x))
        load: np.ndarray = white @ design_matrix([sensor_quaternion(q, r_m) for q in flange])[:, :4]
        return load

    def residual(x: np.ndarray) -> np.ndarray:  # variable projection: the rest is linear
        a = np.hstack([load_columns(x), bias_columns])
        p, *_ = np.linalg.lstsq(a, y, rcond=None)
        residuals: np.ndarray = y - a @ p
        return residuals

    solved = least_squares(residual, np.zeros(3), method="lm")
    mounting_q = _quaternion(start * Rotation.from_rotvec(solved.x))
    load = fit_tool_load([sensor_quaternion(q, mounting_q) for q in flange], means, axis_std,
                         names, samples, limit, times_s, knots, drift)
    a = np.hstack([load_columns(solved.x), bias_columns])
    p, *_ = np.linalg.lstsq(a, y, rcond=None)
    jac = np.hstack([_rotation_jacobian(load_columns, solved.x, p[:4]), a])  # of the model
    dof = len(y) - jac.shape[1]
    s2 = float(np.sum((y - a @ p) ** 2) / dof) if dof > 0 else math.nan
    if drift is not None:
        s2 = max(s2, 1.0)  # never tighter than the noise and drift model
    cov = s2 * np.linalg.pinv(jac.T @ jac)
    std_deg = math.degrees(math.sqrt(max(float(np.trace(cov[:3, :3])), 0.0)))
    return _with_joint_uncertainty(
        _in_flange_frame(load, flange, mounting_q, std_deg, MOUNTING_ESTIMATED), cov[3:, 3:],
        p, knots)


def _rotation_jacobian(columns: Any, x: np.ndarray, p: np.ndarray,
                       step: float = 1e-6) -> np.ndarray:
    """d(model)/d(rotation vector) (rows, 3) by central differences; the model is columns(x) p."""
    out = np.empty((len(columns(x)), 3))
    for k in range(3):
        dx = np.zeros(3)
        dx[k] = step
        out[:, k] = (columns(x + dx) @ p - columns(x - dx) @ p) / (2 * step)
    return out


def _xyzw(q: Quaternion) -> tuple[float, float, float, float]:
    return (q[1], q[2], q[3], q[0])


def _in_flange_frame(load: ToolLoad, flange: list[Quaternion], mounting: Quaternion,
                     std_deg: float, source: str) -> ToolLoad:
    """The fit with its poses named by the robot's orientations and the mounting recorded."""
    poses = tuple(replace(p, quaternion=q) for p, q in zip(load.poses, flange, strict=True))
    return replace(load, poses=poses, mounting_quaternion=mounting, mounting_std_deg=std_deg,
                   mounting_source=source)


def _with_joint_uncertainty(load: ToolLoad, cov: np.ndarray, p: np.ndarray,
                            knots: np.ndarray | None) -> ToolLoad:
    """Uncertainties of m, c, F0, M0 from the 13-parameter covariance (the mounting's share in)."""
    std = np.sqrt(np.maximum(np.diag(cov), 0.0))
    mass, mc = float(p[0]), p[1:4]
    jac = np.hstack([-mc[:, None] / mass**2, np.eye(3) / mass])  # d(mc/m) / d(m, mc)
    com_std = np.sqrt(np.maximum(np.diag(jac @ cov[:4, :4] @ jac.T), 0.0)) * MM_PER_M
    drift_std = drift_fields(p, cov, knots).get("bias_drift_std_per_s")
    return replace(load, mass_std_kg=float(std[0]), com_std_mm=floats(com_std),
                   force_bias_std_n=floats(std[4:7]), torque_bias_std_nm=floats(std[7:10]),
                   bias_drift_std_per_s=drift_std)


__all__ = ["PoseFit", "fit_with_mounting", "initial_mounting"]
