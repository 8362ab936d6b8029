"""``[emulator.tool]``: parsed into the emulated tool, refused by key beyond the sensor's range."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from forcelearn.calibration import Calibration, NoiseEstimate, SensorInfo, ToolLoad
from forcelearn.devices import TOOL_DOWN, quaternion_to_matrix
from forcelearn.emulators.jr3.sensor_model import Jr3ModelParams
from forcelearn.emulators.netft.sensor_model import NetFtModelParams
from forcelearn.emulators.physics.tool import ToolParams, gravity_wrench
from forcelearn.errors import ConfigError
from forcelearn.site.config import load_cell_config
from forcelearn.site.emulated_tool import mounting_rpy_deg, readable_range, rpy_to_quaternion
from forcelearn.site.session import CellSession


def _config(tmp_path: Path, text: str) -> Path:
    path = tmp_path / "cell.toml"
    path.write_text(text)
    return path


def test_without_the_table_the_tool_is_the_default() -> None:
    """No [emulator.tool]: the 0.9 kg tool of every existing result."""
    assert load_cell_config().emulator.tool == ToolParams()


def test_the_table_sets_every_key_and_the_mounting(tmp_path: Path) -> None:
    """mass, centre of mass, contact point; roll-pitch-yaw turned into the same quaternion."""
    config = load_cell_config(_config(tmp_path, (
        "[emulator.tool]\nmass_kg = 2.5\ncom_mm = [10.0, -20.0, 80.0]\n"
        "contact_point_mm = [0.0, 0.0, 200.0]\nmounting_rpy_deg = [10.0, -20.0, 30.0]\n")))
    tool = config.emulator.tool
    assert (tool.mass_kg, tool.com_mm, tool.contact_point_mm) == (
        2.5, (10.0, -20.0, 80.0), (0.0, 0.0, 200.0))
    assert tool.mounting_quaternion == pytest.approx(rpy_to_quaternion((10.0, -20.0, 30.0)))
    assert mounting_rpy_deg(tool.mounting_quaternion) == pytest.approx((10.0, -20.0, 30.0))


def test_the_session_emulates_the_configured_tool(tmp_path: Path) -> None:
    """The emulated physics reads the configured tool (weight seen by the sensor's emulator)."""
    path = _config(tmp_path, "[emulator.tool]\nmass_kg = 4.0\nmounting_quaternion = "
                   "[0.0, 0.0, 0.0, 1.0]\n")
    with CellSession(load_cell_config(path)) as session:
        assert session.physics.tool.mass_kg == 4.0
        assert session.physics.tool.mounting_quaternion == (0.0, 0.0, 0.0, 1.0)


def test_the_mounting_turns_the_sensor_frame_against_the_flange() -> None:
    """The weight with mounting R_m at flange R_f is the weight of an unmounted tool at R_f R_m."""
    rng = np.random.default_rng(3)
    for _ in range(5):
        mounting = rpy_to_quaternion(tuple(rng.uniform(-180, 180, 3)))
        flange = quaternion_to_matrix(rpy_to_quaternion(tuple(rng.uniform(-180, 180, 3))))
        com = tuple(rng.uniform(-100, 100, 3))
        mounted = ToolParams(mass_kg=2.0, com_mm=com, mounting_quaternion=mounting)
        plain = ToolParams(mass_kg=2.0, com_mm=com)
        expected = gravity_wrench(plain, flange @ quaternion_to_matrix(mounting))
        assert gravity_wrench(mounted, flange) == pytest.approx(expected, abs=1e-12)


@pytest.mark.parametrize(("rpy", "mounting", "weight_axis", "sign"), [
    ((0, 0, 0), (1.0, 0.0, 0.0, 0.0), 2, 1.0),                              # Fz = +m g
    ((0, 90, 0), (0.7071067811865476, 0.0, 0.7071067811865476, 0.0), 0, -1.0),  # Fx = -m g
    ((90, 0, 0), (0.7071067811865476, 0.7071067811865476, 0.0, 0.0), 1, 1.0),   # Fy = +m g
], ids=["none", "pitch 90", "roll 90"])
def test_the_documented_conventions_hold_in_the_emulator_and_the_calibration(
        rpy: tuple, mounting: tuple, weight_axis: int, sign: float) -> None:
    """docs/calibration.md's conventions, in the emulator and in the calibration alike.

    Quaternions w first, R_s = R_f R_m; tool down, the weight on the axis and
    with the sign the mounting gives; its moment c x (m g_s); the calibration's
    compensation of that tool removes exactly the emulated reading.
    """
    tool = ToolParams(mass_kg=2.0, com_mm=(30.0, -40.0, 50.0), mounting_quaternion=mounting)
    emulated = gravity_wrench(tool, quaternion_to_matrix(TOOL_DOWN))
    expected_force = np.zeros(3)
    expected_force[weight_axis] = sign * 2.0 * 9.80665
    assert emulated[:3] == pytest.approx(expected_force, abs=1e-9)
    assert emulated[3:] == pytest.approx(np.cross(np.array(tool.com_mm) / 1000, expected_force))
    assert rpy_to_quaternion(rpy) == pytest.approx(mounting)  # w first, fixed axes
    load = ToolLoad(2.0, 0.0, tool.com_mm, (0.0,) * 3, (0.0,) * 3, (0.0,) * 3, (0.0,) * 3,
                    (0.0,) * 3, mounting_quaternion=mounting)
    noise = NoiseEstimate((0.0,) * 6, tuple(tuple(float(i == j) for j in range(6))
                                            for i in range(6)), (0.0,) * 6, 10, 1.0, 10.0)
    cal = Calibration("2026-01-01T00:00:00+00:00", SensorInfo(), noise, load)
    assert cal.compensate(emulated, TOOL_DOWN) == pytest.approx(np.zeros(6), abs=1e-9)


def _heaviest_kg(model: Jr3ModelParams | NetFtModelParams) -> float:
    return float(readable_range(model)[:3].max()) / 9.80665


@pytest.mark.parametrize(
    ("table", "key"),
    [
        ("mass_kg = -0.1", "emulator.tool.mass_kg"),
        ("mass_kg = 1e6", "emulator.tool.mass_kg"),
        ('mass_kg = "heavy"', "emulator.tool.mass_kg"),
        ("mass_kg = 10.0\ncom_mm = [0.0, 0.0, 900.0]", "emulator.tool.com_mm"),
        ("com_mm = [0.0, 0.0, 2500.0]", "emulator.tool.com_mm"),
        ("contact_point_mm = [1.0, 2.0]", "emulator.tool.contact_point_mm"),
        ("mounting_rpy_deg = [0.0, 0.0, 1.0]\nmounting_quaternion = [1.0, 0.0, 0.0, 0.0]",
         "mounting_rpy_deg or mounting_quaternion"),
        ("mounting_quaternion = [1.0, 1.0, 0.0, 0.0]", "emulator.tool.mounting_quaternion"),
        ("weight = 1.0", "emulator.tool.weight"),
    ],
)
def test_a_tool_outside_physical_bounds_is_refused_by_key(tmp_path: Path, table: str,
                                                           key: str) -> None:
    """Each bad value names its key (and the bound) at load."""
    with pytest.raises(ConfigError, match=key.replace(".", r"\.")):
        load_cell_config(_config(tmp_path, f"[emulator.tool]\n{table}\n"))


def test_the_bound_follows_the_sensor_model(tmp_path: Path) -> None:
    """A tool the JR3 model carries is refused on the Net F/T's smaller range, and vice versa."""
    jr3_most, netft_most = _heaviest_kg(Jr3ModelParams()), _heaviest_kg(NetFtModelParams())
    between = (jr3_most + netft_most) / 2
    load_cell_config(_config(tmp_path, f"[emulator.tool]\nmass_kg = {min(jr3_most, netft_most)}"
                             "\ncom_mm = [0.0, 0.0, 0.0]\n"))
    heavier_sensor = "" if jr3_most > netft_most else '[sensor]\nkind = "netft"\n'
    lighter_sensor = '[sensor]\nkind = "netft"\n' if jr3_most > netft_most else ""
    tool = f"[emulator.tool]\nmass_kg = {between}\ncom_mm = [0.0, 0.0, 0.0]\n"
    load_cell_config(_config(tmp_path, heavier_sensor + tool))
    with pytest.raises(ConfigError, match=r"emulator\.tool\.mass_kg"):
        load_cell_config(_config(tmp_path, lighter_sensor + tool))
