"""CellSession applies a calibration file: the filter's R and the cell's compensation."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from forcelearn.calibration import (
    Calibration,
    NoiseEstimate,
    SensorInfo,
    fit_tool_load,
    save_calibration,
)
from forcelearn.devices import Pose
from forcelearn.emulators.physics.cell import quaternion_to_matrix
from forcelearn.emulators.physics.tool import ToolParams, gravity_wrench
from forcelearn.errors import ConfigError
from forcelearn.site.config import load_cell_config
from forcelearn.site.session import CellSession
from forcelearn.tools.experiments.calibration_plan import DEFAULT_POSES, slerp_steps, tilted

FY_VARIANCE = 0.0625
"""R the file gives axis 1 (Fy, the filter's axis): (0.25 N)^2, not the default 0.04."""


FULL_SCALES = (200.0, 200.0, 400.0, 20.0, 20.0, 20.0)
"""The emulated sensor's full scales (N, N*m)."""

def _write_calibration(path: Path) -> None:
    """A calibration of the emulator's true tool, from exact synthetic readings."""
    quaternions = [p.quaternion for p in DEFAULT_POSES]
    readings = np.array([gravity_wrench(ToolParams(), quaternion_to_matrix(q))
                         for q in quaternions])
    covariance = np.diag([0.04, FY_VARIANCE, 0.04, 4e-4, 4e-4, 4e-4])
    noise = NoiseEstimate(bias=(0.0,) * 6, covariance=tuple(tuple(r) for r in covariance.tolist()),
                          drift_per_s=(0.0,) * 6, samples=1000, duration_s=1.0, rate_hz=1000.0)
    sensor = SensorInfo(full_scales=FULL_SCALES, cutoff_hz=125.0)
    cal = Calibration("2024-05-01T00:00:00+00:00", sensor, noise,
                      fit_tool_load(quaternions, readings))
    save_calibration(cal, path)


def _tilted_normal_force(session: CellSession) -> float:
    """Turn the tool 60 deg about world x in free space; return the filtered normal force."""
    cell = session.cell
    here = cell.read_pose()
    for q in slerp_steps(here.quaternion, tilted((1.0, 0.0, 0.0), 60.0), 10.0):
        cell.move_to(Pose(here.x_mm, here.y_mm, here.z_mm, q))
    cell.reset_filter()
    return cell.measure_force_n(400)


def test_a_calibration_file_sets_r_and_compensates_tool_gravity(tmp_path: Path) -> None:
    """With the file: R = its Fy variance, a 60 deg tilt reads ~0 N; without: ~7.6 N."""
    _write_calibration(tmp_path / "cal.toml")
    (tmp_path / "cell.toml").write_text('[calibration]\nfile = "cal.toml"\n')
    with CellSession(load_cell_config(tmp_path / "cell.toml"), seed=5) as session:
        assert session.calibration is not None and session.cell.compensation is not None
        assert session.cell.force_filter.measurement_variance_n2 == pytest.approx(FY_VARIANCE)
        compensated = _tilted_normal_force(session)
    with CellSession(load_cell_config(), seed=5) as session:
        assert session.calibration is None and session.cell.compensation is None
        assert session.cell.force_filter.measurement_variance_n2 == pytest.approx(0.04)
        raw = _tilted_normal_force(session)
    print(f"normal force at a 60 deg tilt: {compensated:.3f} N compensated, {raw:.3f} N raw")
    assert abs(compensated) < 0.2
    assert abs(raw) > 7.0


def test_a_bad_calibration_file_stops_the_session_before_any_device_opens(
        tmp_path: Path) -> None:
    """A file of another format version is a ConfigError naming it; nothing is started."""
    _write_calibration(tmp_path / "cal.toml")
    text = (tmp_path / "cal.toml").read_text().replace("format_version = 3", "format_version = 9")
    (tmp_path / "cal.toml").write_text(text)
    (tmp_path / "cell.toml").write_text('[calibration]\nfile = "cal.toml"\n')
    with pytest.raises(ConfigError, match=r"cal\.toml.*format_version is 9"):
        CellSession(load_cell_config(tmp_path / "cell.toml"))


def _normal_force_back_upright_after_a_tilted_tare(session: CellSession) -> float:
    """Tare at a 60 deg tilt, turn back to the start orientation; the normal force there (N)."""
    cell = session.cell
    here = cell.read_pose()
    _tilted_normal_force(session)
    assert cell.tare(max_reading_n=2.0)
    tilted_pose = cell.read_pose()
    for q in slerp_steps(tilted_pose.quaternion, here.quaternion, 10.0):
        cell.move_to(Pose(here.x_mm, here.y_mm, here.z_mm, q))
    cell.reset_filter()
    return cell.measure_force_n(400)


def test_a_tare_re_derives_the_calibrations_bias_for_the_pose_it_zeroed_at(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """Zeroing at a tilt stores that pose's tool weight; the compensation must follow it.

    The cell re-derives its calibration's bias for the tare's orientation, so
    upright again the tool reads ~0 N. Without that the weight zeroed at the
    tilt shows up as a force of several N.
    """
    _write_calibration(tmp_path / "cal.toml")
    (tmp_path / "cell.toml").write_text('[calibration]\nfile = "cal.toml"\n')
    with CellSession(load_cell_config(tmp_path / "cell.toml"), seed=5) as session:
        followed = _normal_force_back_upright_after_a_tilted_tare(session)
    with CellSession(load_cell_config(tmp_path / "cell.toml"), seed=5) as session:
        monkeypatch.setattr(Calibration, "rezeroed", lambda self, quaternion: self)  # no follow
        stale = _normal_force_back_upright_after_a_tilted_tare(session)
    print(f"upright after a tilted tare: {followed:.3f} N re-derived, {stale:.3f} N not")
    assert abs(followed) < 0.2
    assert abs(stale) > 3.0
