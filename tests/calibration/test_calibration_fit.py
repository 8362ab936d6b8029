"""The pure fits: tool load from synthetic poses, conditioning, noise, matrix check, compensation.

Synthetic readings come from the emulator's own tool physics (an independent
implementation of the same model), so a sign or frame error in either shows up.
"""

from __future__ import annotations

import numpy as np
import pytest

from forcelearn.calibration import (
    MAX_CONDITION,
    TOOL_DOWN,
    Calibration,
    NoiseEstimate,
    SensorInfo,
    check_matrix,
    check_pose_set,
    condition_number,
    estimate_noise,
    fit_tool_load,
    gravity_in_sensor,
    orientation_with_down,
    quaternion_to_matrix,
)
from forcelearn.calibration import STANDARD_GRAVITY_M_S2 as CORE_GRAVITY
from forcelearn.devices import Pose
from forcelearn.emulators.physics.cell import quaternion_to_matrix as emulator_rotation
from forcelearn.emulators.physics.tool import STANDARD_GRAVITY_M_S2, ToolParams, gravity_wrench
from forcelearn.errors import CalibrationError
from forcelearn.tools.experiments.calibration_plan import DEFAULT_POSES, tilted

BIAS = np.array([0.4, -0.3, -8.1, 0.012, -0.02, 0.031])


def _random_quaternions(rng: np.random.Generator, n: int) -> list[tuple[float, ...]]:
    q = rng.normal(size=(n, 4))
    return [tuple(row / np.linalg.norm(row)) for row in q]


def _readings(tool: ToolParams, quaternions, noise: np.ndarray, rng) -> np.ndarray:
    return np.array([
        gravity_wrench(tool, emulator_rotation(q)) + BIAS + noise * rng.standard_normal(6)
        for q in quaternions
    ])


def test_rotation_is_proper_and_maps_known_axes() -> None:
    """The one quaternion_to_matrix is orthonormal; tool-down and 90° about z map as expected."""
    rng = np.random.default_rng(3)
    for q in _random_quaternions(rng, 20):
        r = quaternion_to_matrix(q)
        assert np.allclose(r @ r.T, np.eye(3), atol=1e-12)
        assert np.linalg.det(r) == pytest.approx(1.0)
    down = quaternion_to_matrix((0.0, 1.0, 0.0, 0.0))  # 180° about x: the tool points down
    assert np.allclose(down @ [0, 0, 1], [0, 0, -1]) and np.allclose(down @ [0, 1, 0], [0, -1, 0])
    half = np.sqrt(0.5)
    assert np.allclose(quaternion_to_matrix((half, 0.0, 0.0, half)) @ [1, 0, 0], [0, 1, 0])


def test_gravity_agrees_with_the_emulator_physics() -> None:
    """Core gravity in the sensor frame equals the emulator's tool weight per kg (g = 9.80665)."""
    rng = np.random.default_rng(3)
    for q in _random_quaternions(rng, 20):
        expected = gravity_wrench(ToolParams(1.0, (0.0, 0.0, 0.0)), emulator_rotation(q))[:3]
        assert np.allclose(gravity_in_sensor(q), expected, atol=1e-12)
    assert CORE_GRAVITY == STANDARD_GRAVITY_M_S2


@pytest.mark.parametrize("seed", [0, 1, 2, 3])
def test_fit_recovers_known_parameters_from_noiseless_poses(seed: int) -> None:
    """Exact readings at random poses give back mass, centre of mass and bias exactly."""
    rng = np.random.default_rng(seed)
    tool = ToolParams(float(rng.uniform(0.2, 3.0)), tuple(rng.uniform(-40, 120, 3)))
    quaternions = _random_quaternions(rng, 6)
    fit = fit_tool_load(quaternions, _readings(tool, quaternions, np.zeros(6), rng))
    assert fit.mass_kg == pytest.approx(tool.mass_kg, rel=1e-9)
    assert np.allclose(fit.com_mm, tool.com_mm, atol=1e-7)
    assert np.allclose([*fit.force_bias_n, *fit.torque_bias_nm], BIAS, atol=1e-9)
    assert np.allclose(fit.rms_residual, 0.0, atol=1e-9)


def test_fit_uncertainties_match_the_scatter_of_repeated_noisy_fits() -> None:
    """Over 200 noisy repetitions the stated σ of mass and CoM matches the real spread."""
    rng = np.random.default_rng(11)
    tool = ToolParams(0.9, (3.0, -2.0, 60.0))
    quaternions = [p.quaternion for p in DEFAULT_POSES]
    noise = np.array([0.01, 0.01, 0.01, 0.001, 0.001, 0.001])
    fits = [fit_tool_load(quaternions, _readings(tool, quaternions, noise, rng), noise)
            for _ in range(200)]
    masses = np.array([f.mass_kg for f in fits])
    stated = np.mean([f.mass_std_kg for f in fits])
    print(f"mass: spread {masses.std():.2e} kg, stated {stated:.2e} kg")
    assert abs(masses.mean() - 0.9) < 3 * masses.std() / np.sqrt(200)
    assert 0.75 < stated / masses.std() < 1.3
    com_z = np.array([f.com_mm[2] for f in fits])
    assert 0.75 < np.mean([f.com_std_mm[2] for f in fits]) / com_z.std() < 1.3
    pose_names = [p.name for p in fits[0].poses]
    assert pose_names == [f"pose {i}" for i in range(1, 10)]


@pytest.mark.parametrize(
    ("quaternions", "why"),
    [
        ([TOOL_DOWN], "one orientation"),
        ([TOOL_DOWN, TOOL_DOWN, TOOL_DOWN], "the same orientation three times"),
        ([TOOL_DOWN, tilted((1, 0, 0), 90)], "two orientations"),
        ([TOOL_DOWN, tilted((1, 0, 0), 4), tilted((0, 1, 0), 4)], "tilts of 4 deg"),
        ([TOOL_DOWN, (0.0, 0.0, 1.0, 0.0), (0.0, 0.7071067811865476, 0.7071067811865476, 0.0)],
         "turns about the tool axis only"),
    ],
)
def test_ill_conditioned_pose_sets_are_refused_naming_poses_that_fix_them(quaternions,
                                                                          why: str) -> None:
    """The error names orientations; adding exactly those makes the set well-conditioned."""
    with pytest.raises(CalibrationError, match="ill-conditioned pose set") as caught:
        check_pose_set(quaternions)
    message = str(caught.value)
    assert "add orientations" in message and "quaternion [" in message, why
    suggested = [
        [float(c) for c in part.split("[")[1].split("]")[0].split(",")]
        for part in message.split(" = quaternion")[1:]
    ]
    assert suggested, message
    fixed = [*quaternions, *(tuple(np.array(q) / np.linalg.norm(q)) for q in suggested)]
    assert condition_number(fixed) <= MAX_CONDITION, message


def test_the_default_pose_set_is_well_conditioned_and_never_points_the_tool_up() -> None:
    """Default poses: condition about 3; gravity always has a positive sensor-z component."""
    quaternions = [p.quaternion for p in DEFAULT_POSES]
    assert check_pose_set(quaternions) < 4.0
    assert all(gravity_in_sensor(q)[2] > 0 for q in quaternions)


@pytest.mark.parametrize("axis", [(0, 0, 1), (1, 0, 0), (0, -1, 0), (0, 0, -1), (1, 1, 1)])
def test_orientation_with_down_points_that_sensor_axis_down(axis) -> None:
    """The suggested orientation puts the named sensor direction along gravity."""
    q = orientation_with_down(np.array(axis, dtype=float))
    direction = gravity_in_sensor(q) / np.linalg.norm(gravity_in_sensor(q))
    assert np.allclose(direction, np.array(axis) / np.linalg.norm(axis), atol=1e-9)
    assert abs(np.linalg.norm(q) - 1.0) < 1e-12


def test_a_negative_mass_is_refused_as_a_frame_convention_error() -> None:
    """Readings with gravity of the wrong sign give a clear error, not a negative mass."""
    rng = np.random.default_rng(5)
    quaternions = [p.quaternion for p in DEFAULT_POSES]
    readings = -_readings(ToolParams(), quaternions, np.zeros(6), rng)
    with pytest.raises(CalibrationError, match="quaternion convention"):
        fit_tool_load(quaternions, readings)


def test_noise_estimate_recovers_bias_covariance_drift_and_rate() -> None:
    """Correlated noise with a known covariance, a trend and 1 kHz timestamps is recovered."""
    rng = np.random.default_rng(2)
    root = rng.normal(size=(6, 6)) * 0.05
    covariance = root @ root.T + np.diag([0.04] * 3 + [4e-4] * 3)
    t = np.arange(20000) * 0.001
    drift = np.array([0.02, -0.01, 0.0, 0.001, 0.0, -0.002])
    bias = np.array([0.1, -0.2, 0.3, 0.01, 0.02, 0.03])
    w = rng.multivariate_normal(np.zeros(6), covariance, size=len(t)) + bias + np.outer(
        t - t.mean(), drift)
    noise = estimate_noise(w, t)
    assert np.allclose(noise.covariance, covariance, atol=0.03 * np.max(np.diag(covariance)))
    assert np.allclose(noise.std, np.sqrt(np.diag(covariance)), rtol=0.03)
    assert np.allclose(noise.bias, bias, atol=0.01)
    assert np.allclose(noise.drift_per_s, drift, atol=0.005)
    assert noise.rate_hz == pytest.approx(1000.0)
    with pytest.raises(ValueError, match="at least 10 samples"):
        estimate_noise(w[:5], t[:5])


def test_matrix_check_recovers_a_known_matrix_and_reports_both_residuals() -> None:
    """W = R C^T is solved; the fitted residual is the noise, the sensor's own is larger."""
    rng = np.random.default_rng(4)
    c = np.eye(6) + rng.normal(scale=0.02, size=(6, 6))
    raw = rng.normal(scale=50.0, size=(40, 6))
    applied = raw @ c.T + rng.normal(scale=0.01, size=(40, 6))
    check = check_matrix(raw, applied)
    assert np.allclose(check.matrix, c, atol=1e-3)
    assert all(0.005 < r < 0.02 for r in check.rms_residual_fit)
    assert all(s > 10 * f for s, f in zip(check.rms_residual_sensor, check.rms_residual_fit,
                                           strict=True))
    with pytest.raises(CalibrationError, match="at least 12 loads"):
        check_matrix(raw[:8], applied[:8])
    flat = raw.copy()
    flat[:, 5] = 0.0
    with pytest.raises(CalibrationError, match="all six axes"):
        check_matrix(flat, applied)


def _calibration(tool_fit) -> Calibration:
    noise = NoiseEstimate(bias=(0.0,) * 6, covariance=tuple(tuple(float(i == j) * 0.04
                          for j in range(6)) for i in range(6)), drift_per_s=(0.0,) * 6,
                          samples=100, duration_s=0.1, rate_hz=1000.0)
    return Calibration("2024-01-01T00:00:00+00:00", SensorInfo(), noise, tool_fit)


def test_compensation_removes_bias_and_tool_gravity_in_any_orientation() -> None:
    """Measured - bias - gravity is the contact wrench alone, usable as Cell.compensation."""
    rng = np.random.default_rng(8)
    tool = ToolParams(1.2, (10.0, -5.0, 70.0))
    quaternions = _random_quaternions(rng, 8)
    cal = _calibration(fit_tool_load(quaternions, _readings(tool, quaternions, np.zeros(6),
                                                             rng)))
    contact = np.array([1.0, -19.0, 2.0, 0.3, -0.1, 0.05])
    for q in _random_quaternions(rng, 10):
        measured = gravity_wrench(tool, emulator_rotation(q)) + BIAS + contact
        assert np.allclose(cal.compensation(measured, Pose(900.0, 0.0, 450.0, q)), contact,
                           atol=1e-9)


def test_rezeroed_bias_is_minus_the_tool_weight_at_the_zeroing_pose() -> None:
    """After a zero in free space at q, a reading at q compensates to zero, elsewhere too."""
    rng = np.random.default_rng(9)
    tool = ToolParams(0.9, (0.0, 0.0, 60.0))
    quaternions = [p.quaternion for p in DEFAULT_POSES]
    cal = _calibration(fit_tool_load(quaternions, _readings(tool, quaternions, np.zeros(6),
                                                             rng)))
    zero_q = tilted((1.0, 0.0, 0.0), 30.0)
    offset = gravity_wrench(tool, emulator_rotation(zero_q)) + BIAS  # what zeroing stores
    rezeroed = cal.rezeroed(zero_q)
    for q in (zero_q, TOOL_DOWN, tilted((0.0, 1.0, 0.0), 60.0)):
        measured = gravity_wrench(tool, emulator_rotation(q)) + BIAS - offset
        assert np.allclose(rezeroed.compensate(measured, q), 0.0, atol=1e-9)
    assert cal.tool.mass_kg == rezeroed.tool.mass_kg
