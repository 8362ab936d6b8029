"""``forcelearn calibrate`` on tools other than the default: mounting, range, a moving tool.

The emulated tool is set through ``[emulator.tool]``; the truth is the config.
The study over 20 random tools per cell is ``python -m
forcelearn.tools.calibration_study`` (docs/calibration.md); these tests are its
refusals and one tool end to end.
"""

from __future__ import annotations

import io
import re
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from forcelearn.calibration import MOUNTING_ESTIMATED, MOUNTING_GIVEN
from forcelearn.devices import TOOL_DOWN
from forcelearn.errors import CalibrationError, ConfigError, PoseOutOfRange
from forcelearn.site.config import load_cell_config
from forcelearn.site.session import CellSession
from forcelearn.tools.calibration_study import PLAN
from forcelearn.tools.commands.calibrate import calibrate
from forcelearn.tools.experiments.calibration_plan import NamedPose, tilted

QUICK = replace(PLAN, record_s=0.3, samples_per_pose=120)
"""A test's plan: the default orientations, short recordings."""


def _config(tmp_path: Path, table: str) -> Path:
    path = tmp_path / "cell.toml"
    path.write_text(f"[emulator.tool]\n{table}\n")
    return path


def _chain(exc: BaseException | None) -> list[BaseException]:
    out = []
    while exc is not None:
        out.append(exc)
        exc = exc.__cause__
    return out


def _angle_deg(a: tuple, b: tuple) -> float:
    return float(np.degrees(2 * np.arccos(min(1.0, abs(float(np.dot(a, b)))))))


def test_a_heavy_off_axis_tool_on_a_turned_sensor_is_recovered(tmp_path: Path) -> None:
    """6 kg, 150 mm off axis, sensor turned 45 deg on the flange: within the issue's bounds."""
    path = _config(tmp_path, "mass_kg = 6.0\ncom_mm = [150.0, 0.0, 60.0]\n"
                   "mounting_rpy_deg = [0.0, 0.0, 45.0]")
    truth = load_cell_config(path).emulator.tool
    stream = io.StringIO()
    cal = calibrate(load_cell_config(path), QUICK, out_path=tmp_path / "cal.toml", seed=1,
                    progress=False, stream=stream)
    t = cal.tool
    assert t.mounting_source == MOUNTING_ESTIMATED
    assert "estimated with the tool (none given" in stream.getvalue()
    assert re.search(r"precision: centre of mass sigma \S+ mm .* met; 1 pass\(es\)",
                     stream.getvalue())  # a heavy tool needs no more than one pass
    assert abs(t.mass_kg - truth.mass_kg) <= 0.005 * truth.mass_kg + 0.005
    com_err = float(np.linalg.norm(np.subtract(t.com_mm, truth.com_mm)))
    assert com_err <= 1.0 + 0.005 * float(np.linalg.norm(truth.com_mm))
    assert _angle_deg(t.mounting_quaternion, truth.mounting_quaternion) < 1.0
    assert t.mass_std_kg > 0 and min(t.com_std_mm) > 0 and t.mounting_std_deg > 0


def test_the_mounting_given_in_the_config_is_used_and_said_so(tmp_path: Path) -> None:
    """[calibration] mounting_rpy_deg: taken as given (not estimated), the report says where."""
    path = _config(tmp_path, "mounting_rpy_deg = [0.0, 0.0, 60.0]")
    path.write_text(path.read_text() + "[calibration]\nmounting_rpy_deg = [0.0, 0.0, 60.0]\n")
    config = load_cell_config(path)
    assert config.calibration_mounting == pytest.approx(config.emulator.tool.mounting_quaternion)
    stream = io.StringIO()
    cal = calibrate(config, replace(QUICK, max_passes=1), out_path=tmp_path / "cal.toml",
                    seed=4, progress=False, stream=stream)
    assert cal.tool.mounting_source == MOUNTING_GIVEN and cal.tool.mounting_std_deg == 0.0
    assert cal.tool.mounting_quaternion == pytest.approx(config.calibration_mounting)
    assert "as given ([calibration] mounting_* of the config), not estimated" in stream.getvalue()
    assert abs(cal.tool.mass_kg - config.emulator.tool.mass_kg) < 0.005 * 0.9 + 0.005


@pytest.mark.parametrize("table", [
    "mounting_rpy_deg = [0.0, 0.0, 60.0]\nmounting_quaternion = [1.0, 0.0, 0.0, 0.0]",
    "mounting_quaternion = [1.0, 0.5, 0.0, 0.0]", "mounting_rpy_deg = [0.0, 60.0]",
    "mounting = [0.0, 0.0, 60.0]"], ids=["both", "not unit", "two angles", "unknown key"])
def test_a_bad_mounting_in_the_config_is_refused_by_key(tmp_path: Path, table: str) -> None:
    """[calibration] mounting_*: one of the two, a rotation, named in the refusal."""
    path = tmp_path / "cell.toml"
    path.write_text(f"[calibration]\n{table}\n")
    with pytest.raises(ConfigError, match=r"calibration|\[calibration\]"):
        load_cell_config(path)


def test_a_pose_that_would_saturate_the_sensor_is_refused_before_the_robot_goes(
        tmp_path: Path) -> None:
    """10 kg, 200 mm out along z: a 90 deg tilt would pass 0.9 x 20 N*m; never reached."""
    path = _config(tmp_path, "mass_kg = 10.0\ncom_mm = [0.0, 0.0, 200.0]")
    poses = (NamedPose("down", TOOL_DOWN),
             *(NamedPose(f"tilt 60 {n}", tilted(a, 60.0)) for n, a in (
                 ("+x", (1.0, 0.0, 0.0)), ("+y", (0.0, 1.0, 0.0)), ("-x", (-1.0, 0.0, 0.0)))),
             NamedPose("tilt 90 -y", tilted((0.0, -1.0, 0.0), 90.0)))
    out = tmp_path / "cal.toml"
    with CellSession(load_cell_config(path), seed=2) as session:
        worst = {"moment": 0.0}
        model, measure = session.sensor_emulator.model, session.sensor_emulator.model.measure

        def watched(true_wrench: np.ndarray, dt_s: float, cutoff_hz: float = 0.0) -> list[int]:
            worst["moment"] = max(worst["moment"], float(np.abs(true_wrench[3:]).max()))
            return measure(true_wrench, dt_s, cutoff_hz)

        model.measure = watched
        with pytest.raises(CalibrationError, match=r"pose 5/5 \(tilt 90 -y\) would pass the "
                           r"sensor's range") as caught:
            calibrate(session.config, replace(QUICK, poses=poses), out_path=out,
                      progress=False, session=session, stream=io.StringIO())
    assert any(isinstance(e, PoseOutOfRange) for e in _chain(caught.value))
    assert "the robot was not moved there" in str(caught.value)
    assert 0.0 < worst["moment"] < 0.9 * 20.0  # the sensor never saw the saturating pose
    assert not out.exists()


def test_the_default_plan_skips_a_saturating_pose_and_stays_well_conditioned(
        tmp_path: Path) -> None:
    """Default orientations on a tool whose 60 deg tilts pass the range: skipped, said so, fit."""
    path = _config(tmp_path, "mass_kg = 10.0\ncom_mm = [0.0, 0.0, 230.0]")
    stream = io.StringIO()
    cal = calibrate(load_cell_config(path), QUICK, out_path=tmp_path / "cal.toml", seed=3,
                    progress=False, stream=stream)
    text = stream.getvalue()
    assert "skipped pose 2/9 (tilt 60 deg about world +x)" in text
    assert all("tilt 60" not in p.name for p in cal.tool.poses)
    assert cal.tool.condition_number <= QUICK.max_condition
    assert cal.tool.mass_kg == pytest.approx(10.0, rel=0.005)


def test_a_tool_that_moves_during_the_read_is_refused(tmp_path: Path) -> None:
    """Halfway through a pose's samples the centre of mass shifts 20 mm: refused, no file."""
    path = _config(tmp_path, "mass_kg = 2.0\ncom_mm = [0.0, 0.0, 80.0]")
    out = tmp_path / "cal.toml"
    with CellSession(load_cell_config(path), seed=5) as session:
        physics, read_many = session.physics, session.sensor.read_many
        reads = {"full": 0}

        def slipping(count: int, *args: object) -> list:
            if count != QUICK.samples_per_pose:
                return read_many(count, *args)
            reads["full"] += 1
            first = read_many(count // 2, *args)
            if reads["full"] == 3:  # the third pose: the tool slips in its holder
                physics.tool = replace(physics.tool, com_mm=(20.0, 0.0, 80.0))
            return first + read_many(count - count // 2, *args)

        session.sensor.read_many = slipping
        with pytest.raises(CalibrationError, match="the tool moved during the read") as caught:
            calibrate(session.config, QUICK, out_path=out, progress=False, session=session,
                      stream=io.StringIO())
    assert "pose 3/9" in str(caught.value) and "no calibration file was written" in str(
        caught.value)
    assert not out.exists()
