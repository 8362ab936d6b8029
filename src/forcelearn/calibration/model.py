"""The calibration data model and the compensation it gives the cell.

Units: N, N*m, kg, mm, s, Hz. Wrenches are (Fx, Fy, Fz, Mx, My, Mz) in the
sensor frame; orientations are unit quaternions (w, x, y, z) mapping the sensor
frame to the world frame (world z up), as the robot driver reports them.

The rotation and gravity here are written independently of the emulator's
physics (core must not import emulators); a test checks that both agree.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import Any, cast

import numpy as np

from forcelearn.devices import AXES as AXES  # re-exported: the calibration file names axes
from forcelearn.devices import IDENTITY_QUATERNION, Pose, multiply_quaternions, quaternion_to_matrix
from forcelearn.devices import STANDARD_GRAVITY_M_S2 as STANDARD_GRAVITY_M_S2  # re-exported
from forcelearn.devices import TOOL_DOWN as TOOL_DOWN  # re-exported: the default zero pose

FORMAT_VERSION = 3
"""Version of the calibration file format this code writes (it also reads 2: mounting identity)."""
MOUNTING_GIVEN, MOUNTING_ESTIMATED = "given", "estimated"
"""Where a calibration's mounting rotation came from (``tool.mounting_source``)."""
MM_PER_M = 1000.0

Vec3 = tuple[float, float, float]
Vec6 = tuple[float, float, float, float, float, float]
Quaternion = tuple[float, float, float, float]


def sensor_quaternion(flange: Quaternion, mounting: Quaternion) -> Quaternion:
    """Return the sensor frame's orientation q_f * q_m (sensor -> world) from the flange's."""
    if mounting == IDENTITY_QUATERNION:
        return flange
    return multiply_quaternions(flange, mounting)


def gravity_in_sensor(q: Quaternion) -> np.ndarray:
    """Return gravity g_s (3,) in the sensor frame, m/s^2, for the sensor's orientation ``q``."""
    g_s: np.ndarray = quaternion_to_matrix(q).T @ np.array([0.0, 0.0, -STANDARD_GRAVITY_M_S2])
    return g_s


def floats(values: Any) -> tuple[float, ...]:
    """Return ``values`` flattened to a tuple of Python floats."""
    return tuple(float(v) for v in np.asarray(values, dtype=float).ravel())


@dataclass(frozen=True)
class SensorInfo:
    """What is known of the calibrated sensor and robot (empty strings where unknown)."""

    model: str = ""
    serial: str = ""
    node_id: int = 1
    full_scales: tuple[float, ...] = (0.0,) * 6
    """Full scales in use (N, N, N, N*m, N*m, N*m)."""
    cutoff_hz: float = 0.0
    """The adapter's low-pass cut-off during calibration (the noise depends on it)."""
    robot: str = ""


@dataclass(frozen=True)
class NoiseEstimate:
    """Residual bias and noise right after zeroing, tool in free space at the zeroing pose."""

    bias: tuple[float, ...]
    """Mean reading after zeroing (N, N*m), gravity at the zeroing pose included; ideally 0."""
    covariance: tuple[tuple[float, ...], ...]
    """6x6 noise covariance about a linear trend (N^2, N^2*m, N^2*m^2)."""
    drift_per_s: tuple[float, ...]
    """Slope of that trend (N/s, N*m/s)."""
    samples: int
    duration_s: float
    rate_hz: float
    """Samples per second actually achieved."""
    zero_quaternion: Quaternion = TOOL_DOWN
    """Orientation at which the offsets were zeroed."""

    @property
    def std(self) -> np.ndarray:
        """Noise standard deviation per axis (N, N*m)."""
        return np.sqrt(np.diag(np.asarray(self.covariance)))


@dataclass(frozen=True)
class PoseFit:
    """One static orientation of the tool-load fit."""

    name: str
    quaternion: Quaternion
    samples: int
    mean: tuple[float, ...]
    """Mean reading at the pose (N, N*m)."""
    residual: tuple[float, ...]
    """Mean reading minus the fitted model (N, N*m)."""


@dataclass(frozen=True)
class ToolLoad:
    """The 10-parameter fit's result, each value with its standard uncertainty."""

    mass_kg: float
    mass_std_kg: float
    com_mm: tuple[float, ...]
    com_std_mm: tuple[float, ...]
    force_bias_n: tuple[float, ...]
    """F0: force read with the tool weightless, in the offset state of the fit."""
    force_bias_std_n: tuple[float, ...]
    torque_bias_nm: tuple[float, ...]
    """M0: moment read with the tool weightless, in the offset state of the fit."""
    torque_bias_std_nm: tuple[float, ...]
    condition_number: float
    """Of the column-normalised design matrix (small is good; see ``fit.MAX_CONDITION``)."""
    poses: tuple[PoseFit, ...] = ()
    mounting_quaternion: Quaternion = IDENTITY_QUATERNION
    """R_m (w, x, y, z): the sensor frame against the robot's flange (tool) frame."""
    mounting_std_deg: float = 0.0
    """Uncertainty of the mounting rotation (deg, 1 sigma; 0 when taken as given)."""
    mounting_source: str = MOUNTING_GIVEN
    """``"estimated"`` (fitted with the tool) or ``"given"`` (by the operator, or an older
    file)."""

    @property
    def rms_residual(self) -> np.ndarray:
        """RMS residual per axis over the poses (N, N*m)."""
        rms: np.ndarray = np.sqrt(np.mean(np.square([p.residual for p in self.poses]), axis=0))
        return rms


@dataclass(frozen=True)
class MatrixCheck:
    """Calibration-matrix check from known loads: W = R C^T fitted by least squares."""

    loads: int
    matrix: tuple[tuple[float, ...], ...]
    """C (6x6): applied = C raw."""
    rms_residual_fit: tuple[float, ...]
    """Per-axis RMS of W - R C^T (N, N*m)."""
    rms_residual_sensor: tuple[float, ...]
    """Per-axis RMS of W - R: the sensor's own calibration (N, N*m)."""


@dataclass(frozen=True)
class Calibration:
    """A calibration file's content; :meth:`compensation` is a ``Cell.compensation`` hook."""

    created: str
    """When it was measured (ISO 8601, UTC)."""
    sensor: SensorInfo
    noise: NoiseEstimate
    tool: ToolLoad
    matrix_check: MatrixCheck | None = None
    format_version: int = FORMAT_VERSION
    zeroed_at: Quaternion | None = field(default=None, compare=False)
    """The robot's orientation at the zero the bias is for (None: ``noise.zero_quaternion``);
    set by :meth:`rezeroed`, never written to the file."""
    _gravity_cache: dict[Quaternion, np.ndarray] = field(
        default_factory=dict, repr=False, compare=False
    )

    @property
    def bias(self) -> np.ndarray:
        """The fit's bias (F0, M0) in N and N*m (see ``forcelearn.calibration``)."""
        return np.array([*self.tool.force_bias_n, *self.tool.torque_bias_nm])

    def noise_variance(self, axis: int) -> float:
        """Noise variance of one axis (N^2 or (N*m)^2): the Kalman filter's R."""
        return float(self.noise.covariance[axis][axis])

    def gravity_wrench(self, quaternion: Quaternion) -> np.ndarray:
        """Return the tool's weight in the sensor frame, [m g_s ; c x m g_s] (N, N*m).

        ``quaternion`` is the robot's (flange frame -> world) as it reached it; the
        mounting rotation turns it into the sensor's.
        """
        # Four floats, as ``quaternion`` has four components.
        key = cast(Quaternion, tuple(float(c) for c in quaternion))
        cached = self._gravity_cache.get(key)
        if cached is None:
            force = self.tool.mass_kg * gravity_in_sensor(
                sensor_quaternion(key, self.tool.mounting_quaternion))
            com_m = np.asarray(self.tool.com_mm) / MM_PER_M
            cached = np.concatenate([force, np.cross(com_m, force)])
            if len(self._gravity_cache) >= 64:  # the hot path sees few orientations
                self._gravity_cache.clear()
            self._gravity_cache[key] = cached
        return cached

    def compensate(self, wrench: np.ndarray, quaternion: Quaternion) -> np.ndarray:
        """Return measured - bias - tool gravity (6,), N and N*m, at the robot's ``quaternion``.

        The compensation as a function of the orientation reached: a task that
        turns the tool calls it with the orientation the robot reports.
        """
        compensated: np.ndarray = (
            np.asarray(wrench, dtype=float) - self.bias - self.gravity_wrench(quaternion)
        )
        return compensated

    def compensation(self, wrench: np.ndarray, pose: Pose) -> np.ndarray:
        """``Cell.compensation``: :meth:`compensate` at the pose's orientation."""
        return self.compensate(wrench, pose.quaternion)

    def rezeroed(self, quaternion: Quaternion) -> Calibration:
        """Return a copy whose bias is what zeroing in free space at ``quaternion`` leaves.

        Zeroing stores the whole free-space reading, the tool's weight included,
        so afterwards the weightless reading is minus the weight at that pose.
        """
        bias = -self.gravity_wrench(quaternion)
        tool = replace(self.tool, force_bias_n=floats(bias[:3]), torque_bias_nm=floats(bias[3:]))
        return replace(self, tool=tool, zeroed_at=cast(Quaternion, floats(quaternion)),
                       _gravity_cache={})

    @property
    def zero_quaternion(self) -> Quaternion:
        """The robot's orientation at the zero the bias (F0, M0) is for."""
        return self.zeroed_at if self.zeroed_at is not None else self.noise.zero_quaternion
