"""``forcelearn check``: open both devices of a cell and report on them (unmoved without --turn).

On site, run this first. It opens the robot and the sensor as the config says
(:class:`~forcelearn.site.CellSession`) and lets each device's kind
(:mod:`forcelearn.site.kinds`) report on it. It never moves the robot:

* **computer link**: identifies the controller, reads the pose and status
  (only IDENTIFY, READ_POSITION, READ_STATUS, and the STOP every close sends);
  it reads the controller's move counter before and after and fails if it changed;
* **EGM**: the driver answers the controller with the pose it reports (a
  hold); the session's version, pose, states and traffic counters; fails if
  the target ever differs from the start pose or the controller is not guided;
* **JR3**: initialises the adapter and reads samples for ``--seconds`` (1 s)
  of the sensor's own time (its frame counter: wall time on site, simulated
  time on an emulated cell): mean and noise (standard deviation) per axis, the
  sample rate achieved, and the samples known lost (SYNCs unanswered, frames
  lost, frames left unpaired);
* **Net F/T**: the calibration the box reports, records for ``--seconds``
  (rate, lost, duplicated, out-of-order, rejected datagrams, reboots), mean
  and noise per axis.

With a calibration (``[calibration] file``) it prints the compensated wrench in
free space (:mod:`.check_compensation`): at the present orientation, and with
``--turn`` (the robot moves) at four orientations tilted 30 deg, each judged
against the calibrated tool (3 sigma of its noise).

Each failure names the device and what to check (port, baud, bus, bitrate,
node id) and exits with status 1. With no ``--config`` it checks the built-in
emulated cell.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from forcelearn.errors import LinkError, SafetyStop, SensorError, ToolMismatch, one_line
from forcelearn.site import CellConfig, CellSession, load_cell_config
from forcelearn.site.kinds import Printer
from forcelearn.tools.commands.check_compensation import report_compensation


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``forcelearn check``."""
    parser.add_argument("--config", type=Path, help="cell config TOML (default: emulated cell)")
    parser.add_argument(
        "--seconds", type=float, default=1.0, help="how long to read the sensor, s (1.0)"
    )
    parser.add_argument("--seed", type=int, default=0, help="emulated sensor noise seed (0)")
    parser.add_argument("--turn", action="store_true",
                        help="with a calibration: turn the tool 30 deg about four horizontal "
                        "axes through the tool point and print the compensated wrench at each "
                        "(the robot MOVES; keep a sphere of the tool's length clear)")


def run(args: argparse.Namespace) -> int:
    """Check the cell; 0 if both devices answered as expected, 1 otherwise."""
    if not 0 < args.seconds <= 60:
        print("forcelearn check: --seconds must be in (0, 60]")
        return 2
    config = load_cell_config(args.config)
    source = args.config or "built-in emulated cell"
    print(f"forcelearn check: {source}")
    print(f"  robot   {config.robot_device.describe(config)}")
    print(f"  sensor  {config.sensor_device.describe(config)}")
    missing = missing_devices(config)
    for line in missing:
        print(f"FAILED  {line}")
    if missing:
        return 1
    try:
        with CellSession(config, seed=args.seed) as session:
            check_session(session, args.seconds, print)
            report_compensation(session, print, turn=args.turn)
    except LinkError as exc:
        print(f"FAILED  robot link: {one_line(exc)}")
        return 1
    except SensorError as exc:
        print(f"FAILED  sensor: {one_line(exc)}")
        return 1
    except (SafetyStop, ToolMismatch) as exc:
        print(f"FAILED  {one_line(exc)}")
        return 1
    print("OK      both devices answer; " + (
        "the tool was turned and back" if args.turn else "the robot was not moved"))
    return 0


def check_session(session: CellSession, seconds: float, say: Printer) -> None:
    """Report on an open session's robot and sensor; raises the device's typed error."""
    robot, sensor = session.robot, session.sensor
    if robot is None or sensor is None:
        raise ValueError("check_session needs an open CellSession")
    config = session.config
    unmoved = config.robot_device.check(robot, say)
    config.sensor_device.check(sensor, config, seconds, say)
    unmoved()


def missing_devices(config: CellConfig) -> list[str]:
    """One line per device whose serial port path does not exist (all of them, not the first)."""
    return config.robot_device.missing(config) + config.sensor_device.missing(config)
