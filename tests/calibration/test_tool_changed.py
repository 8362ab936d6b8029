"""The tool changed: free-space readings at a new orientation against the calibrated tool.

And a calibration file of another sensor refused by name.
"""

from __future__ import annotations

from dataclasses import replace
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
from forcelearn.calibration.tool_check import check_free_space
from forcelearn.devices import TOOL_DOWN, Pose, quaternion_to_matrix
from forcelearn.emulators.physics.tool import ToolParams, gravity_wrench
from forcelearn.errors import ConfigError, ToolMismatch
from forcelearn.site.config import load_cell_config
from forcelearn.site.session import CellSession
from forcelearn.tools.cli import main
from forcelearn.tools.experiments.calibration_plan import DEFAULT_POSES, slerp_steps, tilted

FULL_SCALES = (200.0, 200.0, 400.0, 20.0, 20.0, 20.0)
"""The emulated JR3's full scales (N, N*m)."""
STD = (0.2, 0.2, 0.2, 0.02, 0.02, 0.02)
"""The emulated JR3's noise (N, N*m)."""


def _calibration(tool: ToolParams, serial: str = "", node_id: int = 1) -> Calibration:
    """A calibration of ``tool`` from exact readings, with the emulated sensor's noise."""
    quaternions = [p.quaternion for p in DEFAULT_POSES]
    readings = np.array([gravity_wrench(tool, quaternion_to_matrix(q)) for q in quaternions])
    noise = NoiseEstimate(bias=(0.0,) * 6,
                          covariance=tuple(tuple(r) for r in np.diag(np.square(STD)).tolist()),
                          drift_per_s=(0.0,) * 6, samples=1000, duration_s=1.0, rate_hz=1000.0)
    sensor = SensorInfo(serial=serial, node_id=node_id, full_scales=FULL_SCALES, cutoff_hz=125.0)
    return Calibration("2026-01-01T00:00:00+00:00", sensor, noise,
                       fit_tool_load(quaternions, readings))


def _cell(tmp_path: Path, cal: Calibration, extra: str = "") -> Path:
    save_calibration(cal, tmp_path / "cal.toml")
    path = tmp_path / "cell.toml"
    path.write_text(f'{extra}[calibration]\nfile = "cal.toml"\n')
    return path


def _turn(session: CellSession, degrees: float) -> None:
    cell = session.cell
    here = cell.read_pose()
    for q in slerp_steps(here.quaternion, tilted((1.0, 0.0, 0.0), degrees), 10.0):
        cell.move_to(Pose(here.x_mm, here.y_mm, here.z_mm, q))


def test_the_check_needs_a_turn_and_passes_within_three_sigma() -> None:
    """At the zero's orientation nothing shows (False); within 3 sigma fits (True)."""
    cal = _calibration(ToolParams()).rezeroed(TOOL_DOWN)
    turned = tilted((1.0, 0.0, 0.0), 30.0)
    assert check_free_space(cal, np.full(6, 10.0), TOOL_DOWN, cal.zero_quaternion) is False
    assert check_free_space(cal, 2.9 * np.array(STD), turned, cal.zero_quaternion) is True
    with pytest.raises(ToolMismatch, match=r"Fz.*forcelearn calibrate"):
        check_free_space(cal, np.array([0, 0, 3.1 * STD[2], 0, 0, 0]), turned,
                         cal.zero_quaternion)


def test_a_run_with_another_tool_says_so_at_the_next_tare_after_a_turn(tmp_path: Path) -> None:
    """Calibrated 0.9 kg, the emulator carries 1.2 kg: the tare at 40 deg raises ToolMismatch."""
    path = _cell(tmp_path, _calibration(ToolParams()),
                 "[emulator.tool]\nmass_kg = 1.2\n")
    with CellSession(load_cell_config(path), seed=4) as session:
        assert session.cell.check_tool_fit() is False  # at the zero: cannot tell
        _turn(session, 40.0)
        with pytest.raises(ToolMismatch, match="forcelearn calibrate"):
            session.cell.tare(max_reading_n=100.0)


def test_the_calibrated_tool_fits_at_a_turned_orientation(tmp_path: Path) -> None:
    """The same tool at 40 deg: compensated at the orientation reached, within 3 sigma."""
    with CellSession(load_cell_config(_cell(tmp_path, _calibration(ToolParams()))),
                     seed=4) as session:
        _turn(session, 40.0)
        assert session.cell.check_tool_fit(samples=200) is True
        assert session.cell.tare(max_reading_n=100.0)


@pytest.mark.parametrize(
    ("cal_kwargs", "extra", "message"),
    [
        ({"serial": "SN-A"}, "", r"sensor\.serial = 'SN-A'.*sensor_serial = 'SN-B'"),
        ({"node_id": 3}, "", r"sensor\.node_id = 3 but this cell's sensor is node 1"),
        ({}, "[emulator.sensor]\nfull_scales = [400.0, 400.0, 800.0, 40.0, 40.0, 40.0]\n",
         r"sensor\.full_scales"),
    ],
    ids=["serial", "node", "full-scales"],
)
def test_a_calibration_of_another_sensor_is_refused_by_name(
        tmp_path: Path, cal_kwargs: dict, extra: str, message: str) -> None:
    """Serial, node or full scales of another sensor: ConfigError naming the file and key."""
    cal = _calibration(ToolParams(), **cal_kwargs)
    path = _cell(tmp_path, cal, extra)
    path.write_text(path.read_text().replace(
        'file = "cal.toml"', 'file = "cal.toml"\nsensor_serial = "SN-B"'))
    with pytest.raises(ConfigError, match=message) as caught:
        CellSession(load_cell_config(path))
    assert "cal.toml" in str(caught.value) and "another sensor" in str(caught.value)


def test_compensation_is_a_function_of_the_orientation_reached() -> None:
    """compensate(w, q) removes the weight at q, whatever the mounting (a task calls it)."""
    tool = ToolParams(mass_kg=2.0, com_mm=(30.0, 0.0, 90.0))
    cal = _calibration(tool)
    cal = replace(cal, tool=replace(cal.tool, force_bias_n=(0.0,) * 3, torque_bias_nm=(0.0,) * 3))
    for degrees in (0.0, 25.0, 60.0, 90.0):
        q = tilted((0.0, 1.0, 0.0), degrees)
        reading = gravity_wrench(tool, quaternion_to_matrix(q))
        assert cal.compensate(reading, q) == pytest.approx(np.zeros(6), abs=1e-9)


def test_check_turn_prints_the_compensated_wrench_and_flags_another_tool(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """``forcelearn check --turn``: four tilted orientations judged; another tool: FAILED, 1."""
    path = _cell(tmp_path, _calibration(ToolParams()))
    assert main(["check", "--config", str(path), "--turn", "--seconds", "0.2"]) == 0
    printed = capsys.readouterr().out
    assert printed.count("fits (within 3 sigma)") == 4 and "at the zero's orientation" in printed
    assert "the tool was turned and back" in printed
    path.write_text("[emulator.tool]\nmass_kg = 1.3\n" + path.read_text())
    assert main(["check", "--config", str(path), "--turn", "--seconds", "0.2"]) == 1
    printed = capsys.readouterr().out
    assert "DOES NOT FIT" in printed and "FAILED" in printed and "forcelearn calibrate" in printed
