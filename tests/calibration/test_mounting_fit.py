"""The fit with the sensor's mounting (given or estimated); the reading predicted before a turn."""

from __future__ import annotations

import numpy as np
import pytest

from forcelearn.calibration import MOUNTING_ESTIMATED, MOUNTING_GIVEN
from forcelearn.calibration.mounting import fit_with_mounting
from forcelearn.calibration.predict import RANGE_FRACTION, ReadingModel, out_of_range
from forcelearn.devices import multiply_quaternions, quaternion_to_matrix
from forcelearn.emulators.physics.tool import ToolParams, gravity_wrench
from forcelearn.errors import CalibrationError
from forcelearn.site.emulated_tool import rpy_to_quaternion
from forcelearn.tools.experiments.calibration_plan import DEFAULT_POSES, tilted

STD = np.array([0.2, 0.2, 0.2, 0.02, 0.02, 0.02])
"""Per-sample noise (N, N*m) of the emulated JR3."""
SAMPLES = 500
QUATERNIONS = [p.quaternion for p in DEFAULT_POSES]


def _readings(tool: ToolParams, quaternions: list, rng: np.random.Generator,
              bias: np.ndarray) -> np.ndarray:
    """Mean readings of ``SAMPLES`` noisy samples at each flange orientation."""
    return np.array([gravity_wrench(tool, quaternion_to_matrix(q)) + bias
                     + rng.normal(0.0, 1.0, 6) * STD / np.sqrt(SAMPLES) for q in quaternions])


def _angle_deg(a: tuple, b: tuple) -> float:
    return float(np.degrees(2 * np.arccos(min(1.0, abs(float(np.dot(a, b)))))))


@pytest.mark.parametrize("seed", range(4))
def test_any_tool_and_mounting_is_recovered_within_its_uncertainty(seed: int) -> None:
    """Random tool (0.1..15 kg, centre of mass up to 200 mm out), random mounting: estimated."""
    rng = np.random.default_rng(seed)
    radius, azimuth = rng.uniform(0, 200), rng.uniform(0, 2 * np.pi)
    tool = ToolParams(mass_kg=float(np.exp(rng.uniform(np.log(0.1), np.log(15.0)))),
                      com_mm=(radius * np.cos(azimuth), radius * np.sin(azimuth),
                              rng.uniform(0, 250)),
                      mounting_quaternion=rpy_to_quaternion(tuple(rng.uniform(-180, 180, 3))))
    load = fit_with_mounting(QUATERNIONS, _readings(tool, QUATERNIONS, rng, rng.normal(0, 2, 6)),
                             STD / np.sqrt(SAMPLES))
    assert load.mounting_source == MOUNTING_ESTIMATED
    assert abs(load.mass_kg - tool.mass_kg) < 5 * load.mass_std_kg
    assert np.all(np.abs(np.subtract(load.com_mm, tool.com_mm)) < 5 * np.array(load.com_std_mm))
    assert _angle_deg(load.mounting_quaternion, tool.mounting_quaternion) < max(
        5 * load.mounting_std_deg, 1e-3)
    assert [p.quaternion for p in load.poses] == QUATERNIONS  # the robot's, as fitted


def test_a_given_mounting_is_used_as_given() -> None:
    """Given the true mounting, the linear fit runs in the sensor frame: no rotation fitted."""
    rng = np.random.default_rng(7)
    mounting = rpy_to_quaternion((0.0, 0.0, 45.0))
    tool = ToolParams(mass_kg=3.0, com_mm=(50.0, 0.0, 80.0), mounting_quaternion=mounting)
    load = fit_with_mounting(QUATERNIONS, _readings(tool, QUATERNIONS, rng, np.zeros(6)),
                             STD / np.sqrt(SAMPLES), mounting=mounting)
    assert (load.mounting_source, load.mounting_std_deg) == (MOUNTING_GIVEN, 0.0)
    assert load.mounting_quaternion == mounting
    assert load.mass_kg == pytest.approx(3.0, rel=1e-3)


def _about_vertical(q: tuple, angle_deg: float) -> tuple:
    return multiply_quaternions((np.cos(np.radians(angle_deg) / 2), 0.0, 0.0,
                                 np.sin(np.radians(angle_deg) / 2)), q)


@pytest.mark.parametrize(
    "quaternions",
    [
        [tilted((1.0, 0.0, 0.0), 0.0), tilted((1.0, 0.0, 0.0), 60.0)],
        # one tilt turned about the vertical: gravity stays put in the sensor frame
        [_about_vertical(tilted((1.0, 0.0, 0.0), 45.0), d) for d in (0, 90, 180, 270)],
        # tilts about one horizontal axis: gravity directions in one plane
        [tilted((1.0, 0.0, 0.0), d) for d in (0.0, 20.0, 40.0, 60.0)],
    ],
    ids=["too-few", "coplanar-turned-about-vertical", "coplanar-one-tilt-axis"],
)
def test_too_few_or_coplanar_orientations_are_refused(quaternions: list) -> None:
    """Both leave mass, centre of mass and bias tangled: refused, orientations to add named."""
    readings = np.zeros((len(quaternions), 6))
    with pytest.raises(CalibrationError, match=r"ill-conditioned pose set.*add orientations"):
        fit_with_mounting(quaternions, readings, STD)


def test_four_orientations_predict_the_reading_anywhere() -> None:
    """Tool down and three 10 deg probes determine the reading at a 60 deg tilt, any mounting."""
    tool = ToolParams(mass_kg=6.0, com_mm=(120.0, -60.0, 90.0),
                      mounting_quaternion=rpy_to_quaternion((30.0, 0.0, 100.0)))
    probes = [tilted((1.0, 0.0, 0.0), 0.0), tilted((1.0, 0.0, 0.0), 10.0),
              tilted((0.0, 1.0, 0.0), 10.0), tilted((-1.0, 0.0, 0.0), 10.0)]
    model = ReadingModel(STD)
    assert not model.determined
    offset = gravity_wrench(tool, quaternion_to_matrix(probes[0]))  # zeroed at the first
    for q in probes:
        model.add(q, gravity_wrench(tool, quaternion_to_matrix(q)) - offset, SAMPLES)
    assert model.determined
    far = tilted((0.0, -1.0, 0.0), 60.0)
    predicted, std = model.predict(far)
    truth = gravity_wrench(tool, quaternion_to_matrix(far)) - offset
    assert predicted == pytest.approx(truth, abs=1e-9)
    assert np.all(std > 0)
    worst = np.maximum(np.abs(truth), np.abs(gravity_wrench(tool, quaternion_to_matrix(far))))
    full_scales = worst / RANGE_FRACTION * 1.5 + 1.0
    assert out_of_range(model, far, full_scales) == []
    axis = int(np.argmax(worst[3:])) + 3
    full_scales[axis] = worst[axis] / RANGE_FRACTION * 0.9
    assert len(out_of_range(model, far, full_scales)) == 1
