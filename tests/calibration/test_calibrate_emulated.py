"""``forcelearn calibrate`` against the emulated cell: accuracy against known truth, and failures.

The truth is read from the emulator itself: its tool (``ToolParams()``), its
noise (``Jr3ModelParams``) and, sample by sample, its drifting bias minus
the stored offset, logged by wrapping the sensor model.
"""

from __future__ import annotations

import io
import os
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from forcelearn.calibration import MAX_CONDITION, load_calibration
from forcelearn.emulators.jr3.sensor_model import Jr3ModelParams
from forcelearn.emulators.physics.tool import ToolParams
from forcelearn.errors import CalibrationError, RobotFault, SafetyStop, SensorStale
from forcelearn.site.config import load_cell_config
from forcelearn.site.session import CellSession
from forcelearn.tools.cli import main
from forcelearn.tools.commands.calibrate import calibrate
from forcelearn.tools.experiments.calibration_plan import (
    CalibrationPlan,
    NamedPose,
    slerp_steps,
    tilted,
)

SEEDS = range(*(int(v) for v in os.environ.get("FORCELEARN_CALIBRATION_SEEDS", "0:5").split(":")))
"""Seeds of the accuracy test; FORCELEARN_CALIBRATION_SEEDS=5:25 measures 20 more."""
FAST = CalibrationPlan(record_s=2.0, samples_per_pose=800, settle_s=0.2, settle_timeout_s=5.0,
                       max_passes=1)
"""Short recordings, one pass: the test budget, not the site's (5 s and 500 samples there)."""


class TruthLog:
    """Logs, per emulated sample, (bias - offset) and the true wrench; notes each zeroing."""

    def __init__(self, session: CellSession) -> None:
        model = session.sensor_emulator.model
        self.rows: list[np.ndarray] = []
        self.zeros: list[int] = []
        measure, zero = model.measure, model.zero

        def logged_measure(true_wrench: np.ndarray, dt_s: float, cutoff_hz: float = 0) -> list[int]:
            counts = measure(true_wrench, dt_s, cutoff_hz)
            self.rows.append(np.concatenate([model.bias - model.offset, true_wrench]))
            return counts

        def logged_zero(true_wrench: np.ndarray) -> None:
            zero(true_wrench)
            self.zeros.append(len(self.rows))

        model.measure, model.zero = logged_measure, logged_zero


def _chain(exc: BaseException) -> list[BaseException]:
    out = []
    while exc is not None:
        out.append(exc)
        exc = exc.__cause__
    return out


@pytest.mark.parametrize("seed", SEEDS)  # one test per seed: the workers share them out
def test_estimates_match_the_emulator_truth_over_five_seeds(seed: int, tmp_path: Path) -> None:
    """Mass within 2 %, CoM within 2 mm, bias within 0.05 N, noise std within 10 %, per seed."""
    truth_tool, model = ToolParams(), Jr3ModelParams()
    out = tmp_path / f"cal{seed}.toml"
    with CellSession(load_cell_config(), seed=seed) as session:
        truth = TruthLog(session)
        cal = calibrate(session.config, FAST, out_path=out, seed=seed, progress=False,
                        session=session, stream=io.StringIO())
    assert load_calibration(out) == cal
    rows = np.array(truth.rows)
    start = truth.zeros[-1]
    window = rows[start:start + cal.noise.samples]
    true_residual_bias = (window[:, :6] + window[:, 6:]).mean(axis=0)
    # with the bias drift fitted, F0 and M0 are the bias at the first pose (tool down, read
    # right after the noise, no turn between): its samples follow the noise's
    first_pose = start + cal.noise.samples
    true_tool_bias = rows[first_pose:first_pose + FAST.samples_per_pose, :6].mean(axis=0)
    mass_err = abs(cal.tool.mass_kg - truth_tool.mass_kg) / truth_tool.mass_kg
    com_err = float(np.linalg.norm(np.subtract(cal.tool.com_mm, truth_tool.com_mm)))
    resid_err = np.abs(np.subtract(cal.noise.bias, true_residual_bias))
    force_err = np.abs(np.subtract(cal.tool.force_bias_n, true_tool_bias[:3]))
    torque_err = np.abs(np.subtract(cal.tool.torque_bias_nm, true_tool_bias[3:]))
    std_err = np.abs(cal.noise.std / np.array(model.noise_std) - 1.0)
    print("\nseed  mass err %  CoM err mm  resid-bias err N  tool-bias err N  "
          "torque-bias err N·m  noise-std err %")
    print(f"{seed:4d}  {100 * mass_err:10.3f}  {com_err:10.3f}  {resid_err[:3].max():16.4f}"
          f"  {force_err.max():15.4f}  {torque_err.max():19.5f}  {100 * std_err.max():15.2f}")
    assert mass_err < 0.02
    assert com_err < 2.0
    assert resid_err[:3].max() < 0.05 and resid_err[3:].max() < 0.005
    # the bias at one knot is read from fewer samples than a constant bias: 4 of its sigmas
    assert np.all(force_err < np.maximum(0.05, 4 * np.asarray(cal.tool.force_bias_std_n)))
    assert np.all(torque_err < np.maximum(0.005, 4 * np.asarray(cal.tool.torque_bias_std_nm)))
    assert std_err.max() < 0.10
    assert cal.noise.rate_hz > 100 and cal.tool.condition_number < MAX_CONDITION
    assert cal.tool.bias_drift_per_s is not None  # the first orientation was revisited


def _assert_no_file(out: Path) -> None:
    assert not out.exists()
    assert not out.with_name(f"{out.stem}-residuals.png").exists()


def test_a_sensor_that_goes_silent_mid_calibration_ends_clearly_without_a_file(
        tmp_path: Path) -> None:
    """The adapter stops answering during the pose loop: SensorStale named, robot stopped."""
    out = tmp_path / "cal.toml"
    config = tmp_path / "cell.toml"
    config.write_text("[safety]\nstale_sensor_s = 2.0\n")  # not the emulated cell's 10 s
    with CellSession(load_cell_config(config), seed=1) as session:
        emulator, robot = session.sensor_emulator, session.robot_emulator
        emulator.frame_hook = lambda frame: None if robot.move_count > 25 else frame
        with pytest.raises(CalibrationError) as caught:
            calibrate(session.config, FAST, out_path=out, progress=False, session=session)
    message = str(caught.value)
    assert "pose " in message and "SensorStale" in message, message
    assert "no calibration file was written" in message
    assert any(isinstance(e, SensorStale) for e in _chain(caught.value))
    _assert_no_file(out)


def test_a_robot_that_refuses_a_pose_ends_clearly_without_a_file(tmp_path: Path) -> None:
    """The controller refuses the 60 deg tilts (J5 limited to 130..180 deg): RobotFault named."""
    config_path = tmp_path / "cell.toml"
    config_path.write_text(
        "[emulator.arm]\njoint_limits_deg = [[-170, 170], [-70, 110], [-165, -5], "
        "[-180, 180], [130, 180], [-180, 180]]\n")
    out = tmp_path / "cal.toml"
    with pytest.raises(CalibrationError) as caught:
        calibrate(load_cell_config(config_path), FAST, out_path=out, progress=False)
    message = str(caught.value)
    assert "pose 2/9 (tilt 60 deg about world +x)" in message and "J5" in message, message
    assert "no calibration file was written" in message
    assert any(isinstance(e, RobotFault) for e in _chain(caught.value))
    _assert_no_file(out)


def test_a_position_outside_the_workspace_is_refused_before_leaving_it(tmp_path: Path) -> None:
    """A free-space position beyond the [safety] box: SafetyStop, never outside, no file."""
    out = tmp_path / "cal.toml"
    plan = replace(FAST, position_mm=(1150.0, 0.0, 450.0))
    with CellSession(load_cell_config(), seed=2) as session:
        with pytest.raises(CalibrationError) as caught:
            calibrate(session.config, plan, out_path=out, progress=False, session=session)
        assert session.robot_emulator.pose.x_mm <= 1100.0
    message = str(caught.value)
    assert "moving to the free-space position" in message and "outside the workspace" in message
    assert any(isinstance(e, SafetyStop) for e in _chain(caught.value))
    _assert_no_file(out)


def test_an_ill_conditioned_pose_set_is_refused_before_the_robot_moves(tmp_path: Path) -> None:
    """Three near-identical orientations: refused up front, poses to add named, no motion."""
    out = tmp_path / "cal.toml"
    poses = (NamedPose("down", tilted((1.0, 0.0, 0.0), 0.0)),
             NamedPose("a", tilted((1.0, 0.0, 0.0), 3.0)),
             NamedPose("b", tilted((0.0, 1.0, 0.0), 3.0)))
    with CellSession(load_cell_config(), seed=3) as session:
        with pytest.raises(CalibrationError, match="ill-conditioned pose set") as caught:
            calibrate(session.config, replace(FAST, poses=poses), out_path=out,
                      progress=False, session=session)
        assert session.robot_emulator.move_count == 0
    assert "add orientations" in str(caught.value) and "tool horizontal" in str(caught.value)
    _assert_no_file(out)


def test_manual_mode_reads_the_poses_the_operator_jogged_to(tmp_path: Path) -> None:
    """--manual: the tool never commands a move; the operator's poses are read back and fitted."""
    out = tmp_path / "cal.toml"
    poses = (NamedPose("down", tilted((1.0, 0.0, 0.0), 0.0)),
             NamedPose("x 50", tilted((1.0, 0.0, 0.0), 50.0)),
             NamedPose("skipped", tilted((1.0, 1.0, 0.0), 20.0)),
             NamedPose("y 50", tilted((0.0, 1.0, 0.0), 50.0)),
             NamedPose("-x 50", tilted((-1.0, 0.0, 0.0), 50.0)))
    with CellSession(load_cell_config(), seed=4) as session:
        robot, emulator = session.robot, session.robot_emulator
        prompts: list[str] = []
        jogged = {"moves": 0}

        def operator(prompt: str) -> str:  # jogs with the "pendant", here the driver
            prompts.append(prompt)
            for pose in poses:
                if f": {pose.name} (" in prompt:
                    if pose.name == "skipped":
                        return "s"
                    here = robot.read_pose()
                    for q in slerp_steps(here.quaternion, pose.quaternion, 10.0):
                        robot.move_to(type(here)(here.x_mm, here.y_mm, here.z_mm, q))
                        jogged["moves"] += 1
            return ""

        cal = calibrate(session.config, replace(FAST, poses=poses), out_path=out, manual=True,
                        ask=operator, progress=False, session=session)
        assert emulator.move_count == jogged["moves"]  # every move was the operator's
    assert "free space" in prompts[0] and len(prompts) == 6
    assert [p.name for p in cal.tool.poses] == ["down", "x 50", "y 50", "-x 50"]
    assert cal.tool.mass_kg == pytest.approx(0.9, rel=0.02)
    assert out.exists()


def test_cli_writes_file_and_figure_with_the_matrix_check(tmp_path: Path, capsys) -> None:
    """``forcelearn calibrate --loads`` prints ± figures and per-axis residuals, writes both."""
    rng = np.random.default_rng(0)
    raw = rng.normal(scale=40.0, size=(24, 6))
    applied = raw @ (np.eye(6) + 0.01 * rng.normal(size=(6, 6))).T
    loads = tmp_path / "loads.csv"
    header = [f"{k}_{a}" for k in ("raw", "applied") for a in ("fx", "fy", "fz", "mx", "my", "mz")]
    loads.write_text(",".join(["note", *header]) + "\n" + "\n".join(
        ",".join(["w", *(repr(float(v)) for v in row)]) for row in np.hstack([raw, applied])))
    out = tmp_path / "site" / "cal.toml"
    code = main(["calibrate", "--out", str(out), "--record-s", "0.3", "--samples-per-pose", "100",
                 "--settle-s", "0", "--loads", str(loads), "--no-progress", "--sensor-serial",
                 "SN 42", "--max-passes", "1"])
    printed = capsys.readouterr().out
    assert code == 0
    assert "mass" in printed and " ± " in printed and "calibration-matrix check" in printed
    assert "precision: centre of mass sigma" in printed and "1 pass(es)" in printed
    cal = load_calibration(out)
    assert cal.sensor.serial == "SN 42" and cal.matrix_check is not None
    assert cal.matrix_check.loads == 24 and max(cal.matrix_check.rms_residual_fit) < 1e-9
    png = out.with_name("cal-residuals.png").read_bytes()
    assert png.startswith(b"\x89PNG")


def test_cli_reports_a_bad_poses_file_and_writes_nothing(tmp_path: Path, capsys) -> None:
    """A poses file with a bad quaternion: exit 1, message names the pose, no file."""
    poses = tmp_path / "poses.toml"
    poses.write_text("[[pose]]\nname = 'x'\nquaternion = [1.0, 1.0, 0.0, 0.0]\n")
    out = tmp_path / "cal.toml"
    assert main(["calibrate", "--out", str(out), "--poses", str(poses), "--no-progress"]) == 1
    assert "pose[0]" in capsys.readouterr().err
    _assert_no_file(out)
