"""The tool-load fit with a drifting bias: knots at the revisits of the first orientation."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from forcelearn.calibration import (
    Calibration,
    SensorInfo,
    estimate_noise,
    fit_tool_load,
    load_calibration,
    save_calibration,
)
from forcelearn.calibration.fit import bias_knots
from forcelearn.calibration.mounting import fit_with_mounting
from forcelearn.emulators.physics.cell import quaternion_to_matrix
from forcelearn.emulators.physics.tool import ToolParams, gravity_wrench
from forcelearn.errors import CalibrationError
from forcelearn.tools.experiments.calibration_plan import DEFAULT_POSES, tilted

NOISE = np.array([0.02, 0.02, 0.02, 0.002, 0.002, 0.002])
"""Standard error of a pose's mean reading (N, N*m)."""
BIAS0 = np.array([0.4, -0.3, 0.8, 0.012, -0.02, 0.031])
DRIFT = np.array([2e-3, -3e-3, 1e-3, 2e-4, -3e-4, 1e-4])
"""Linear bias drift of the synthetic sensor (N/s, N*m/s): 10 standard errors over the run."""
TOOL = ToolParams(0.5, (20.0, -15.0, 90.0))
SECONDS_PER_POSE = 8.0


def _sequence(revisit_every: int) -> list[tuple[float, float, float, float]]:
    """The default plan's orientations with the first one again every few poses and at the end."""
    first, rest = DEFAULT_POSES[0].quaternion, [p.quaternion for p in DEFAULT_POSES[1:]]
    out = [first]
    for k, q in enumerate(rest, start=1):
        out.append(q)
        if revisit_every and k % revisit_every == 0 and k < len(rest):
            out.append(first)
    return [*out, first] if revisit_every else out


def _record(quaternions, rng: np.random.Generator, drift: np.ndarray = DRIFT
            ) -> tuple[np.ndarray, np.ndarray]:
    """Mean readings and their times: tool load + bias0 + drift * t + noise."""
    times = np.arange(len(quaternions)) * SECONDS_PER_POSE
    means = np.array([gravity_wrench(TOOL, quaternion_to_matrix(q)) + BIAS0 + drift * t
                      + NOISE * rng.standard_normal(6) for q, t in zip(quaternions, times,
                                                                        strict=True)])
    return means, times


@pytest.mark.parametrize("mounting", [None, (1.0, 0.0, 0.0, 0.0)], ids=["estimated", "given"])
def test_a_known_drift_is_recovered_and_the_tool_with_it(mounting) -> None:
    """Drift, mass and centre of mass come back within 4 of their stated sigmas."""
    rng = np.random.default_rng(5)
    quaternions = _sequence(2)
    means, times = _record(quaternions, rng)
    load = fit_with_mounting(quaternions, means, NOISE, mounting=mounting, times_s=times)
    assert load.bias_drift_per_s is not None and load.bias_drift_std_per_s is not None
    drift_err = np.abs(np.subtract(load.bias_drift_per_s, DRIFT))
    assert np.all(drift_err < 4 * np.asarray(load.bias_drift_std_per_s)), drift_err
    assert abs(load.mass_kg - TOOL.mass_kg) < 4 * load.mass_std_kg
    com_err = np.abs(np.subtract(load.com_mm, TOOL.com_mm))
    assert np.all(com_err < 4 * np.asarray(load.com_std_mm)), com_err
    bias_err = np.abs(np.subtract([*load.force_bias_n, *load.torque_bias_nm], BIAS0))
    stated = np.asarray([*load.force_bias_std_n, *load.torque_bias_std_nm])
    assert np.all(bias_err < 4 * stated), bias_err  # the bias at the first pose's time
    constant = fit_with_mounting(quaternions, means, NOISE, mounting=mounting)
    assert constant.bias_drift_per_s is None
    constant_err = np.linalg.norm(np.subtract(constant.com_mm, TOOL.com_mm))
    assert np.linalg.norm(com_err) < constant_err  # the drift, unmodelled, shifts the tool


def test_the_stated_drift_uncertainty_matches_the_scatter() -> None:
    """Over 200 noisy repetitions the stated sigma of the drift matches its real spread."""
    rng = np.random.default_rng(9)
    quaternions = _sequence(2)
    fits = []
    for _ in range(200):
        means, times = _record(quaternions, rng)
        fits.append(fit_tool_load(quaternions, means, NOISE, times_s=times,
                                  knots_s=bias_knots(quaternions, times)))
    drifts = np.array([f.bias_drift_per_s for f in fits])
    stated = np.mean([f.bias_drift_std_per_s for f in fits], axis=0)
    ratio = stated / drifts.std(axis=0)
    assert np.all((ratio > 0.75) & (ratio < 1.3)), ratio
    assert np.all(np.abs(drifts.mean(axis=0) - DRIFT) < 4 * drifts.std(axis=0) / np.sqrt(200))


def test_without_a_revisit_the_bias_is_fitted_constant() -> None:
    """No second visit to the first orientation: no knots, no drift claimed."""
    quaternions = _sequence(0)
    times = np.arange(len(quaternions)) * SECONDS_PER_POSE
    assert bias_knots(quaternions, times) is None
    means, _ = _record(quaternions, np.random.default_rng(1), drift=np.zeros(6))
    load = fit_with_mounting(quaternions, means, NOISE, times_s=times)
    assert load.bias_drift_per_s is None and load.bias_drift_std_per_s is None


@pytest.mark.parametrize("quaternions", [
    [DEFAULT_POSES[0].quaternion, tilted((1, 0, 0), 60.0), DEFAULT_POSES[0].quaternion],
    [DEFAULT_POSES[0].quaternion, (0.0, 0.0, 1.0, 0.0),
     (0.0, 0.7071067811865476, 0.7071067811865476, 0.0), DEFAULT_POSES[0].quaternion],
], ids=["two orientations", "turns about the tool axis only"])
def test_too_few_or_coplanar_orientations_are_still_refused(quaternions) -> None:
    """A revisit adds no gravity direction: the pose set is refused as before."""
    times = np.arange(len(quaternions)) * SECONDS_PER_POSE
    means = np.zeros((len(quaternions), 6))
    with pytest.raises(CalibrationError, match="ill-conditioned pose set"):
        fit_with_mounting(quaternions, means, NOISE, times_s=times)


def test_the_drift_round_trips_through_the_file(tmp_path: Path) -> None:
    """The fitted drift and its sigma are written and read back exactly."""
    rng = np.random.default_rng(3)
    quaternions = _sequence(2)
    means, times = _record(quaternions, rng)
    tool = fit_with_mounting(quaternions, means, NOISE, times_s=times)
    noise = estimate_noise(rng.normal(scale=0.2, size=(200, 6)), np.arange(200) * 1e-3)
    cal = Calibration("2024-05-01T12:00:00+00:00", SensorInfo(
        full_scales=(200.0, 200.0, 400.0, 20.0, 20.0, 20.0), cutoff_hz=125.0), noise, tool)
    save_calibration(cal, tmp_path / "cal.toml")
    assert load_calibration(tmp_path / "cal.toml") == cal
    constant = replace(cal, tool=replace(tool, bias_drift_per_s=None, bias_drift_std_per_s=None))
    save_calibration(constant, tmp_path / "constant.toml")
    assert "bias_drift" not in (tmp_path / "constant.toml").read_text()
    assert load_calibration(tmp_path / "constant.toml") == constant
