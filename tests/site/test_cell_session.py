"""The emulated cell through the real drivers: config, start force, the safety paths."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest

from forcelearn.emulators.jr3.faults import Jr3FaultConfig
from forcelearn.errors import ConfigError, SensorStale
from forcelearn.site.config import load_cell_config
from forcelearn.site.session import CellSession
from forcelearn.tasks.surface import SurfaceTask


@pytest.fixture()
def session():
    """An emulated cell with the default config, closed after the test."""
    with CellSession(load_cell_config(), seed=1) as opened:
        yield opened


def test_default_config_is_the_emulated_cell_with_section_5_values() -> None:
    """No file: emulated robot and sensor, γ = 0.8, specialized α = 1, 19.61 N."""
    config = load_cell_config()
    assert config.robot_emulated and config.sensor_emulated
    assert config.learner.gamma == 0.8 and config.learner.alpha_specialized == 1.0
    assert config.task.desired_force_n == pytest.approx(19.6133)
    assert config.sensor.stale_timeout_s == config.safety.stale_sensor_s


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("[safety]\nmax_force_n = 0\n", "safety.max_force_n"),
        ("[safety]\nmax_force_n = inf\n", "cannot be switched off"),
        ("[safety]\nstale_sensor_s = -1\n", "safety.stale_sensor_s"),
        ("[robot]\nlimits = 1\n", "set the limits in \\[safety\\]"),
        ("[sensor]\nnode = 3\n", "sensor.node"),
        ("[emulator.sponge]\nstiffness = 3\n", "emulator.sponge.stiffness"),
        ("[task]\nretract_y_mm = 0\n", "retract_y_mm"),
    ],
)
def test_bad_cell_configs_name_the_key(tmp_path: Path, text: str, message: str) -> None:
    """Each bad key or value is a ConfigError that names it; limits cannot be disabled."""
    path = tmp_path / "cell.toml"
    path.write_text(text)
    with pytest.raises(ConfigError, match=message):
        load_cell_config(path)


def test_reset_presses_into_the_sponge_and_measures_the_start_force(session) -> None:
    """The start pose gives a plausible contact force through pty, CAN and the filter."""
    config = session.config
    task = SurfaceTask(session.cell, config.task, config.safety.max_step_mm)
    assert task.reset().tolist() == [0.0]
    assert 5.0 < task.start_force_n < 20.0
    pose = session.robot_emulator.pose  # measured once in position: within the band
    band = config.emulator.arm.in_position_mm
    assert pose.y_mm == pytest.approx(config.task.start_mm[1], abs=band)
    assert pose.z_mm == pytest.approx(config.task.start_mm[2], abs=band)
    assert session.robot_emulator.engine.motion.target == config.task.start_pose()


def test_pressing_past_the_force_limit_fails_the_step_and_retracts(session) -> None:
    """A 40 mm-deep command meets the backing: limit hit on the way, trial failed, pulled out."""
    config = session.config
    task = SurfaceTask(session.cell, config.task, config.safety.max_step_mm)
    task.reset()
    outcome = task.step(np.array([config.task.start_mm[1] - 40.0]))
    assert outcome.failed and outcome.extras["limit_hit"] == 1.0
    band = config.emulator.arm.in_position_mm
    assert session.robot_emulator.pose.y_mm == pytest.approx(config.task.retract_y_mm, abs=band)
    assert session.sponge is not None and session.sponge.passes == 1


def test_a_silent_sensor_stops_the_robot_and_raises_stale(tmp_path: Path) -> None:
    """When the adapter goes silent the watchdog raises SensorStale and motion stops."""
    path = tmp_path / "cell.toml"
    path.write_text("[safety]\nstale_sensor_s = 0.5\n")
    with CellSession(load_cell_config(path), seed=1) as session:
        _silent_sensor_stops(session)


def _silent_sensor_stops(session: CellSession) -> None:
    config = session.config
    task = SurfaceTask(session.cell, config.task, config.safety.max_step_mm)
    task.reset()
    moves = session.robot_emulator.move_count
    session.sensor_emulator.set_faults(Jr3FaultConfig(silent=True))
    with pytest.raises(SensorStale):
        task.step(np.array([config.task.start_mm[1]]))
    assert session.robot_emulator.move_count == moves + 1  # the step's move, nothing after
    assert not session.robot.read_status().moving


def test_a_step_over_the_limit_is_refused_before_it_reaches_the_robot(session) -> None:
    """A 30 mm jump is refused by the driver: SafetyStop, the emulator never moved."""
    from forcelearn.errors import SafetyStop

    moves = session.robot_emulator.move_count
    pose = session.cell.read_pose()
    with pytest.raises(SafetyStop, match="max_step_mm"):
        session.cell.move_to(pose.moved(dz_mm=-30.0))
    assert session.robot_emulator.move_count == moves


def test_a_target_outside_the_workspace_is_refused(session) -> None:
    """Stepping out of the [safety] workspace box is refused before any byte is sent."""
    from forcelearn.errors import SafetyStop

    high = session.config.safety.workspace_max_mm
    pose = session.cell.read_pose()
    target = pose.moved(dz_mm=high[2] - pose.z_mm + 5.0)
    moves = session.robot_emulator.move_count
    with pytest.raises(SafetyStop, match="workspace"):
        session.cell.move_in_steps(target, session.config.safety.max_step_mm)
    assert session.robot_emulator.pose.z_mm <= high[2]
    assert session.robot_emulator.move_count >= moves  # stopped at the edge, never past it


def test_the_watchdog_is_longer_only_for_the_in_process_emulated_sensor(tmp_path: Path) -> None:
    """Emulated sensor: 1 s unless set; a real bus keeps 0.1 s; an explicit value always wins."""
    assert load_cell_config().sensor.stale_timeout_s == 10.0
    real = tmp_path / "real.toml"
    real.write_text('[sensor]\ninterface = "socketcan"\nchannel = "can0"\n')
    assert load_cell_config(real).sensor.stale_timeout_s == 0.1
    explicit = tmp_path / "explicit.toml"
    explicit.write_text("[safety]\nstale_sensor_s = 0.2\n")
    assert load_cell_config(explicit).sensor.stale_timeout_s == 0.2


def _drift_fy(session: CellSession, change_n: float) -> None:
    """Move the emulated JR3's Fy bias by ``change_n`` (a drift since it was zeroed)."""
    model = session.sensor_emulator.model
    state = model.state_dict()
    state["bias"] = state["bias"] + np.array([0.0, change_n, 0.0, 0.0, 0.0, 0.0])
    model.load_state_dict(state)


def _start_force_after_drift(tare: bool, change_n: float) -> tuple[float, float, CellSession]:
    """(measured start force, true start force) of one trial after a drift of Fy's bias."""
    config = load_cell_config()
    config = dataclasses.replace(
        config, task=dataclasses.replace(config.task, tare_each_trial=tare)
    )
    with CellSession(config, seed=1) as session:
        _drift_fy(session, change_n)
        task = SurfaceTask(session.cell, config.task, config.safety.max_step_mm)
        task.reset()
        true_n = float(-session.physics.true_wrench()[1])  # the normal force: -Fy
        return task.start_force_n, true_n, session


def test_a_tare_before_the_press_takes_a_drifted_bias_out_of_the_start_force() -> None:
    """Fy's bias drifts 1.5 N after zeroing: the start force is 1.5 N off unless tared.

    With ``task.tare_each_trial`` the sensor is zeroed in free space above the
    start (retract Y) before the press, so the measured force is the contact
    force again. A drift past ``task.tare_max_reading_n`` (2 N) is not zeroed:
    that much in free space may be a touch, which zeroing would hide.
    """
    drifted, true_drifted, untared = _start_force_after_drift(False, 1.5)
    assert drifted - true_drifted == pytest.approx(-1.5, abs=0.3)  # the force axis is -Fy
    assert untared.cell.tares == 0
    tared, true_tared, session = _start_force_after_drift(True, 1.5)
    assert tared - true_tared == pytest.approx(0.0, abs=0.3)
    assert (session.cell.tares, session.cell.tares_refused) == (1, 0)
    refused, true_refused, session = _start_force_after_drift(True, 3.0)
    assert refused - true_refused == pytest.approx(-3.0, abs=0.3)
    assert (session.cell.tares, session.cell.tares_refused) == (0, 1)
