"""``forcelearn calibrate``: measure bias, noise and the tool's load; write the calibration file.

::

    forcelearn calibrate                          # the emulated cell (default config)
    forcelearn calibrate --config site.toml       # the real cell; same code
    forcelearn calibrate --config site.toml --manual --loads loads.csv

Steps (details in :mod:`.calibration_run` and docs/calibration.md): optional
calibration-matrix check from ``--loads`` (done first, so a bad CSV fails
before the robot moves); free-space position; bias and noise; tool load over
the plan's orientations; the report; then the PNG of residuals and last the
calibration TOML, both written atomically. Any failure ends with a message
naming the step and **no calibration file written**.

The output defaults to the ``[calibration] file`` of the config (so ``run``
and ``check`` pick it up), else ``calibration.toml``. The session is opened
*without* the old calibration, so a damaged file never blocks a new one.

Loads CSV: a header row with ``raw_fx, raw_fy, raw_fz, raw_mx, raw_my, raw_mz``
(the sensor's readings, N and N*m) and ``applied_fx .. applied_mz`` (the
known wrench, same units and frame); other columns are ignored; 12 rows or more.
"""

from __future__ import annotations

import argparse
import contextlib
import csv
import datetime
import sys
from dataclasses import replace
from pathlib import Path
from typing import TextIO

import numpy as np

from forcelearn.calibration import (
    AXES,
    MOUNTING_ESTIMATED,
    Calibration,
    MatrixCheck,
    SensorInfo,
    check_matrix,
    save_calibration,
)
from forcelearn.calibration.model import Quaternion
from forcelearn.errors import CalibrationError, ConfigError, ForcelearnError
from forcelearn.site import CellConfig, CellSession, load_cell_config
from forcelearn.site.emulated_tool import mounting_rpy_deg, rpy_to_quaternion
from forcelearn.tools.commands.calibrate_guard import GuardedCalibrator
from forcelearn.tools.experiments.calibration_plan import (
    DEFAULT_POSES,
    CalibrationPlan,
    load_poses,
)
from forcelearn.tools.experiments.calibration_run import Ask
from forcelearn.tools.figures.calibration import write_residual_png

LOAD_COLUMNS = [f"{kind}_{axis.lower()}" for kind in ("raw", "applied") for axis in AXES]


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``forcelearn calibrate``."""
    defaults = CalibrationPlan()
    parser.add_argument("--config", type=Path, help="cell config TOML (default: emulated cell)")
    parser.add_argument("--out", type=Path, help="calibration TOML to write (default: the "
                        "config's [calibration] file, else calibration.toml)")
    parser.add_argument("--figure", type=Path, help="PNG of residuals (default: <out>-residuals"
                        ".png)")
    parser.add_argument("--poses", type=Path, help="TOML of orientations (and position_mm)")
    parser.add_argument("--position", type=float, nargs=3, metavar=("X", "Y", "Z"),
                        help=f"free-space tool point, mm (default {defaults.position_mm})")
    parser.add_argument("--record-s", type=float, default=defaults.record_s,
                        help="bias-and-noise recording time, s (default %(default)s)")
    parser.add_argument("--samples-per-pose", type=int, default=defaults.samples_per_pose,
                        help="samples averaged per orientation (default %(default)s)")
    parser.add_argument("--revisit-every", type=int, default=defaults.revisit_every,
                        help="measure the first orientation again after every N poses and at "
                        "the end, for the bias drift (0: never; default %(default)s)")
    parser.add_argument("--max-passes", type=int, default=defaults.max_passes,
                        help="most passes over the orientations to bring the centre of mass's "
                        "sigma under a third of 1 mm + 0.5 %% of its distance (default "
                        "%(default)s)")
    parser.add_argument("--settle-s", type=float, default=defaults.settle_s,
                        help="dwell at each pose before the settling check, s "
                        "(default %(default)s)")
    parser.add_argument("--settle-timeout-s", type=float, default=defaults.settle_timeout_s,
                        help="longest wait for a pose to settle, s (default %(default)s)")
    parser.add_argument("--max-rotation-step-deg", type=float,
                        default=defaults.max_rotation_step_deg,
                        help="largest turn per move command, deg (default %(default)s)")
    parser.add_argument("--manual", action="store_true",
                        help="ask the operator to jog to each pose and press Enter")
    parser.add_argument("--loads", type=Path, help="CSV of known loads for the 6x6 matrix check")
    parser.add_argument("--sensor-model", default=None, help="sensor model, for the file")
    parser.add_argument("--sensor-serial", default="", help="sensor serial number, for the file")
    mounting = parser.add_mutually_exclusive_group()
    mounting.add_argument("--mounting-rpy-deg", type=float, nargs=3, metavar=("R", "P", "Y"),
                          help="the sensor's mounting on the flange as given: roll x, pitch y, "
                          "yaw z about fixed axes, deg (default: estimated with the tool)")
    mounting.add_argument("--mounting-quaternion", type=float, nargs=4,
                          metavar=("W", "X", "Y", "Z"), help="the same as a quaternion "
                          "(sensor frame -> flange frame, RAPID order)")
    parser.add_argument("--seed", type=int, help="emulated sensor noise seed (default [run] seed)")
    parser.add_argument("--no-progress", action="store_true", help="no progress bar")


def run(args: argparse.Namespace) -> int:
    """Run the calibration as the options say; returns 0 (errors raise ForcelearnError)."""
    config = load_cell_config(args.config)
    plan = CalibrationPlan(
        record_s=args.record_s, samples_per_pose=args.samples_per_pose, settle_s=args.settle_s,
        revisit_every=args.revisit_every, max_passes=args.max_passes,
        settle_timeout_s=args.settle_timeout_s,
        max_rotation_step_deg=args.max_rotation_step_deg,
    )
    if args.poses is not None:
        poses, position = load_poses(args.poses)
        plan = replace(plan, poses=poses, position_mm=position or plan.position_mm)
    if args.position is not None:
        plan = replace(plan, position_mm=tuple(args.position))
    calibrate(
        config, plan, out_path=args.out, figure_path=args.figure, manual=args.manual,
        loads_path=args.loads, sensor_model=args.sensor_model, sensor_serial=args.sensor_serial,
        seed=config.seed if args.seed is None else args.seed, progress=not args.no_progress,
        mounting=mounting_option(args.mounting_rpy_deg, args.mounting_quaternion),
    )
    return 0


def calibrate(
    config: CellConfig,
    plan: CalibrationPlan,
    *,
    out_path: Path | None = None,
    figure_path: Path | None = None,
    manual: bool = False,
    ask: Ask = input,
    loads_path: Path | None = None,
    sensor_model: str | None = None,
    sensor_serial: str = "",
    seed: int = 0,
    progress: bool = True,
    stream: TextIO | None = None,
    session: CellSession | None = None,
    mounting: Quaternion | None = None,
) -> Calibration:
    """Measure, report and write; raises CalibrationError (no file written) on any failure.

    ``session``: an open cell to use (the caller closes it); default: open one
    from ``config`` without its calibration file, closed at the end.
    ``mounting``: the sensor's mounting on the flange (w, x, y, z) as given on the command
    line; None: the config's ``[calibration] mounting_*`` if set, else estimated.
    With the default orientations, poses out of the sensor's range are skipped and
    orientations added where the fit needs them; with others, either is refused.
    """
    stream = stream or sys.stdout
    given_by = "--mounting-rpy-deg/--mounting-quaternion"
    if mounting is None and config.calibration_mounting is not None:
        mounting, given_by = config.calibration_mounting, "[calibration] mounting_* of the config"
    out = Path(out_path or config.calibration_file or "calibration.toml")
    figure = Path(figure_path or out.with_name(f"{out.stem}-residuals.png"))
    try:
        check = check_matrix(*read_loads(loads_path)) if loads_path else None
        opened = session or CellSession(replace(config, calibration_file=None), seed=seed)
        with opened if session is None else contextlib.nullcontext(opened):
            sensor = _sensor_info(config, opened, sensor_model, sensor_serial)
            calibrator = GuardedCalibrator(
                opened, plan, full_scales=sensor.full_scales, mounting=mounting,
                complete=plan.poses == DEFAULT_POSES, manual=manual, ask=ask,
                progress=progress, out=stream)
            measurement = calibrator.run()
        cal = Calibration(
            created=datetime.datetime.now(datetime.UTC).isoformat(timespec="seconds"),
            sensor=sensor, noise=measurement.noise, tool=measurement.tool, matrix_check=check,
        )
        print(report(cal, given_by), file=stream)
        write_residual_png(cal, figure)
        save_calibration(cal, out)
    except OSError as exc:
        raise CalibrationError(f"could not write {exc.filename or out}: {exc}; "
                               f"no calibration file was written to {out}") from exc
    except ForcelearnError as exc:
        raise CalibrationError(f"{exc}; no calibration file was written to {out}") from exc
    print(f"wrote {out} and {figure}; to use it, put in the cell config:\n"
          f"[calibration]\nfile = \"{out}\"", file=stream)
    return cal


def mounting_option(rpy_deg: list[float] | None,
                    quaternion: list[float] | None) -> Quaternion | None:
    """The mounting given on the command line, or None (estimated); ConfigError if no rotation."""
    if rpy_deg is not None:
        return rpy_to_quaternion((rpy_deg[0], rpy_deg[1], rpy_deg[2]))
    if quaternion is None:
        return None
    q = np.asarray(quaternion, dtype=float)
    norm = float(np.linalg.norm(q))
    if not np.all(np.isfinite(q)) or abs(norm - 1.0) > 1e-3:
        raise ConfigError(f"--mounting-quaternion {quaternion}: a unit quaternion (w, x, y, z)")
    w, x, y, z = (float(c) / norm for c in q)
    return (w, x, y, z)


def read_loads(path: Path) -> tuple[np.ndarray, np.ndarray]:
    """Read the loads CSV; return (raw, applied), each (n, 6). ConfigError names the line."""
    try:
        with open(path, newline="") as handle:
            rows = list(csv.reader(handle))
    except OSError as exc:
        raise ConfigError(f"cannot read loads file {str(path)!r}: {exc}") from exc
    if not rows:
        raise ConfigError(f"loads file {str(path)!r} is empty")
    header = [h.strip().lower() for h in rows[0]]
    missing = [c for c in LOAD_COLUMNS if c not in header]
    if missing:
        raise ConfigError(f"loads file {str(path)!r}: missing column(s) {missing}")
    index = [header.index(c) for c in LOAD_COLUMNS]
    values = []
    for line, row in enumerate(rows[1:], start=2):
        if not any(cell.strip() for cell in row):
            continue
        try:
            values.append([float(row[i]) for i in index])
        except (ValueError, IndexError) as exc:
            raise ConfigError(f"loads file {str(path)!r} line {line}: {exc}") from exc
    table = np.array(values, dtype=float).reshape(-1, 12)
    if not np.all(np.isfinite(table)):
        raise ConfigError(f"loads file {str(path)!r}: values must be finite")
    return table[:, :6], table[:, 6:]


def report(cal: Calibration, given_by: str = "--mounting-*") -> str:
    """Return the human-readable result: parameters ± uncertainty, residuals, noise.

    ``given_by``: where a given mounting came from (the command line or the config).
    """
    t, n = cal.tool, cal.noise

    def pm(values: tuple[float, ...], stds: tuple[float, ...], digits: int) -> str:
        return ", ".join(f"{v:.{digits}f} ± {s:.{digits}f}" for v, s in zip(values, stds,
                                                                              strict=True))

    why = ("estimated with the tool (none given: a sensor's clocking on its plate is often "
           "not the drawing's)" if t.mounting_source == MOUNTING_ESTIMATED
           else f"as given ({given_by}), not estimated")
    lines = [
        f"tool load ({len(t.poses)} poses, condition number {t.condition_number:.2f}):",
        f"  mass            {t.mass_kg:.4f} ± {t.mass_std_kg:.4f} kg",
        f"  mounting        quaternion [{', '.join(f'{c:.4f}' for c in t.mounting_quaternion)}]"
        f" ± {t.mounting_std_deg:.3f} deg, roll-pitch-yaw "
        f"{np.round(mounting_rpy_deg(t.mounting_quaternion), 2).tolist()} deg: {why}",
        f"  centre of mass  ({pm(t.com_mm, t.com_std_mm, 2)}) mm",
        f"  force bias      ({pm(t.force_bias_n, t.force_bias_std_n, 3)}) N",
        f"  torque bias     ({pm(t.torque_bias_nm, t.torque_bias_std_nm, 4)}) N·m"
        + (" (at the first pose)" if t.bias_drift_per_s is not None else ""),
        (f"  bias drift      ({pm(t.bias_drift_per_s, t.bias_drift_std_per_s or (0.0,) * 6, 5)})"
         " N/s, N·m/s (the first orientation revisited)" if t.bias_drift_per_s is not None
         else "  bias drift      not fitted (the first orientation was not revisited)"),
        "residual per pose (N, N·m):",
        f"  {'pose':<30}" + "".join(f"{a:>9}" for a in AXES),
    ]
    lines += [f"  {p.name[:30]:<30}" + "".join(f"{r:9.4f}" for r in p.residual) for p in t.poses]
    lines.append(f"  {'RMS':<30}" + "".join(f"{r:9.4f}" for r in t.rms_residual))
    lines += [
        f"noise after zeroing ({n.samples} samples, {n.duration_s:.2f} s, {n.rate_hz:.0f}/s):",
        f"  {'':<30}" + "".join(f"{a:>9}" for a in AXES),
        f"  {'residual bias':<30}" + "".join(f"{v:9.4f}" for v in n.bias),
        f"  {'std':<30}" + "".join(f"{v:9.4f}" for v in n.std),
        f"  {'drift per s':<30}" + "".join(f"{v:9.4f}" for v in n.drift_per_s),
    ]
    if cal.matrix_check is not None:
        lines += _matrix_lines(cal.matrix_check)
    return "\n".join(lines)


def _matrix_lines(check: MatrixCheck) -> list[str]:
    return [
        f"calibration-matrix check ({check.loads} loads), RMS residual per axis:",
        f"  {'':<30}" + "".join(f"{a:>9}" for a in AXES),
        f"  {'sensor own matrix':<30}" + "".join(f"{v:9.4f}" for v in check.rms_residual_sensor),
        f"  {'fitted 6x6 matrix':<30}" + "".join(f"{v:9.4f}" for v in check.rms_residual_fit),
    ]


def _sensor_info(
    config: CellConfig, opened: CellSession, sensor_model: str | None, serial: str
) -> SensorInfo:
    """What the calibration file records of the sensor and robot (the kinds say)."""
    robot, sensor = opened.robot, opened.sensor
    if robot is None or sensor is None:  # pragma: no cover
        raise CalibrationError("the cell session did not open its devices")
    robot_name = config.robot_device.calibration_name(robot)
    info: SensorInfo = config.sensor_device.calibration_info(
        config, sensor, robot_name, sensor_model, serial
    )
    return info
