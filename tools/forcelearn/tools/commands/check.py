"""``forcelearn check``: open both devices of a cell and report on them, without moving the robot.

On site, run this first. It opens the robot link and the CAN bus as the config
says (:class:`~forcelearn.site.session.CellSession`), identifies the
controller, reads the pose and status, initialises the JR3 adapter and reads
samples for ``--seconds`` (1 s) of the sensor's own time (its frame counter:
wall time on site, simulated time on an emulated cell): mean and noise
(standard deviation) per axis, the sample rate achieved, and the samples
known lost (SYNCs unanswered, frames lost, frames left unpaired). It sends no motion command: only
IDENTIFY, READ_POSITION, READ_STATUS, and the STOP every close sends; it
reads the controller's move counter before and after and fails if it changed.

Over EGM (``[robot] kind = "egm"``) and a Net F/T (``[sensor] kind = "netft"``)
the checks of :mod:`.check_ethernet` run instead (an EGM session that only
holds; the box's calibration and its record counts).

Each failure names the device and what to check (port, baud, bus, bitrate,
node id) and exits with status 1. With no ``--config`` it checks the built-in
emulated cell.
"""

from __future__ import annotations

import argparse
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

from forcelearn.devices import AXES, WrenchSample
from forcelearn.drivers.jr3_can.driver import Jr3CanSensor
from forcelearn.errors import LinkError, SafetyStop, SensorError, one_line
from forcelearn.protocols.computer_link import messages
from forcelearn.protocols.jr3_can.opcodes import CounterMeaning
from forcelearn.site.config import CellConfig, load_cell_config
from forcelearn.site.session import CellSession
from forcelearn.tools.commands.check_ethernet import (
    check_egm,
    check_egm_unmoved,
    check_netft,
    describe_egm,
    describe_netft,
)

UNITS = ("N", "N", "N", "N*m", "N*m", "N*m")
BATCH = 20
"""Samples per read_many call while sampling (a 20 ms slice at 1 kHz)."""

Printer = Callable[[str], None]


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``forcelearn check``."""
    parser.add_argument("--config", type=Path, help="cell config TOML (default: emulated cell)")
    parser.add_argument(
        "--seconds", type=float, default=1.0, help="how long to read the sensor, s (1.0)"
    )
    parser.add_argument("--seed", type=int, default=0, help="emulated sensor noise seed (0)")


def run(args: argparse.Namespace) -> int:
    """Check the cell; 0 if both devices answered as expected, 1 otherwise."""
    if not 0 < args.seconds <= 60:
        print("forcelearn check: --seconds must be in (0, 60]")
        return 2
    config = load_cell_config(args.config)
    source = args.config or "built-in emulated cell"
    print(f"forcelearn check: {source}")
    print(f"  robot   {_describe_robot(config)}")
    print(f"  sensor  {_describe_bus(config)}")
    missing = missing_devices(config)
    for line in missing:
        print(f"FAILED  {line}")
    if missing:
        return 1
    try:
        with CellSession(config, seed=args.seed) as session:
            check_session(session, args.seconds, print)
    except LinkError as exc:
        print(f"FAILED  robot link: {one_line(exc)}")
        return 1
    except SensorError as exc:
        print(f"FAILED  sensor: {one_line(exc)}")
        return 1
    except SafetyStop as exc:
        print(f"FAILED  {one_line(exc)}")
        return 1
    print("OK      both devices answer; the robot was not moved")
    return 0


def check_session(session: CellSession, seconds: float, say: Printer) -> None:
    """Report on an open session's robot and sensor; raises the device's typed error."""
    robot, sensor = session.robot, session.sensor
    if robot is None or sensor is None:
        raise ValueError("check_session needs an open CellSession")
    if session.config.robot_kind == "egm":
        held = check_egm(robot, say)
        _check_any_sensor(session, seconds, say)
        check_egm_unmoved(robot, held, say)
        return
    major, minor = messages.PROTOCOL_VERSION
    say(f"  robot   controller {robot.controller_model!r}, computer link {major}.x "
        f"(this driver speaks {major}.{minor})")
    pose = robot.read_pose()
    say(f"  robot   pose x {pose.x_mm:.2f}  y {pose.y_mm:.2f}  z {pose.z_mm:.2f} mm, "
        f"quaternion (w x y z) {' '.join(f'{q:.4f}' for q in pose.quaternion)}")
    before = robot.read_status()
    say(f"  robot   {'MOVING' if before.moving else 'still'}, last error {before.last_error}, "
        f"{before.move_count} moves since power-up")
    _check_any_sensor(session, seconds, say)
    after = robot.read_status()
    if after.move_count != before.move_count:
        raise SafetyStop(
            f"the controller's move counter went from {before.move_count} to "
            f"{after.move_count} during the check: something else commands this robot; "
            "stop and find it before running"
        )


def _check_any_sensor(session: CellSession, seconds: float, say: Printer) -> None:
    if session.config.sensor_kind == "netft":
        check_netft(session.sensor, session.config, seconds, say)
    else:
        _check_sensor(session.sensor, session.config, seconds, say)


def _check_sensor(sensor: Jr3CanSensor, config: CellConfig, seconds: float, say: Printer) -> None:
    cfg = config.jr3
    scales = sensor.full_scales
    say(f"  sensor  JR3 node {cfg.node_id} initialised: {cfg.mode} mode, cut-off "
        f"{sensor.cutoff_hz:g} Hz, offsets {'zeroed' if cfg.zero_on_init else 'as stored'}")
    if scales is not None:
        say(f"  sensor  full scales {' '.join(f'{s:g}' for s in scales[:3])} N, "
            f"{' '.join(f'{s:g}' for s in scales[3:])} N*m")
    stats_before = sensor.stats
    samples, elapsed, clock = read_for(sensor, seconds)
    stats = sensor.stats
    wrench = np.array([s.wrench for s in samples])
    mean, noise = wrench.mean(axis=0), wrench.std(axis=0)
    say(f"  sensor  {len(samples)} samples in {elapsed:.2f} s of {clock} time: "
        f"{len(samples) / elapsed:.0f} samples/s; "
        f"dropped {stats.dropped_samples - stats_before.dropped_samples} "
        f"(SYNCs unanswered {stats.unanswered_syncs - stats_before.unanswered_syncs}, "
        f"frames lost {stats.lost_frames - stats_before.lost_frames}, "
        f"unpaired {stats.unpaired_frames - stats_before.unpaired_frames}), "
        f"bootups {stats.bootups - stats_before.bootups}, "
        f"rejected frames {stats.rejected_total - stats_before.rejected_total}")
    say("          axis        mean   noise (std)")
    for name, unit, m, n in zip(AXES, UNITS, mean, noise, strict=True):
        say(f"          {name}  {m:>+10.3f}  {n:>10.3f}  {unit}")
    axis, sign = config.filter.axis, config.filter.sign
    say(f"  sensor  normal force ({'+' if sign > 0 else '-'}{AXES[axis]}, [filter] axis "
        f"{axis}): mean {sign * mean[axis]:+.3f} N, noise {noise[axis]:.3f} N")
    if config.calibration_file is not None:
        state = "found" if config.calibration_file.is_file() else "MISSING"
        say(f"  sensor  calibration file {config.calibration_file}: {state}")


def read_for(sensor: Jr3CanSensor, seconds: float) -> tuple[list[WrenchSample], float, str]:
    """Read samples for ``seconds`` of the sensor's own time: (samples, seconds, "sensor").

    The adapter's frame counter is the sensor's clock (each sample's ``sensor_dt_s``):
    on site it runs with the wall clock, on an emulated cell with the simulated one, so
    a 60 s check of an emulated sensor reads 60 s worth of samples in a few seconds.
    Samples that do not carry their sensor time (older firmware) are read for
    ``seconds`` of wall time: (samples, seconds, "wall").
    """
    samples: list[WrenchSample] = []
    opcodes = getattr(getattr(sensor, "config", None), "opcodes", None)
    on_sensor_clock = getattr(opcodes, "counter", None) is CounterMeaning.SENSOR_FRAMES
    sensor_s = 0.0
    start = time.monotonic()
    while True:
        batch = sensor.read_many(BATCH)
        samples += batch
        if on_sensor_clock:  # None: the first sample after a (re)start, no time known
            sensor_s += sum(s.sensor_dt_s or 0.0 for s in batch)
            if sensor_s >= seconds:
                return samples, sensor_s, "sensor"
        elif (wall_s := time.monotonic() - start) >= seconds:
            return samples, wall_s, "wall"


def missing_devices(config: CellConfig) -> list[str]:
    """One line per device whose serial port path does not exist (all of them, not the first)."""
    lines = []
    robot_url = getattr(config.robot, "url", "")  # EGM and Net F/T are reached over UDP
    if (
        robot_url
        and not config.robot_emulated
        and "://" not in robot_url
        and not Path(robot_url).exists()
    ):
        lines.append(f"robot link: port {robot_url} does not exist; check [robot] url and the "
                     "cable" + _EMULATE_HINT)
    channel = config.bus.channel
    slcan = config.sensor_kind == "jr3" and config.bus.interface == "slcan"
    if slcan and "://" not in channel and not Path(channel).exists():
        lines.append(f"sensor: slcan adapter port {channel} does not exist; check the channel in "
                     "[sensor] and that the USB-CAN adapter is plugged in" + _EMULATE_HINT)
    return lines


_EMULATE_HINT = (" (for `forcelearn emulate`, name the stable links it prints, which survive "
                 "restarts, rather than the /dev/pts paths)")


def _describe_robot(config: CellConfig) -> str:
    if config.robot_kind == "egm":
        return describe_egm(config)
    robot = config.link
    if config.robot_emulated:
        return "built-in robot-controller emulator on a pty"
    return (f"port {robot.url} at {robot.baudrate} baud, {robot.bytesize}"
            f"{robot.parity}{robot.stopbits:g}")


def _describe_bus(config: CellConfig) -> str:
    if config.sensor_kind == "netft":
        return describe_netft(config)
    bus = config.bus
    if config.sensor_emulated:
        return "built-in JR3 emulator on a virtual CAN bus"
    described = (f"CAN interface {bus.interface}, channel {bus.channel}, {bus.bitrate} bit/s, "
                 f"JR3 node {config.jr3.node_id}")
    if bus.interface == "slcan" and bus.sleep_after_open_s is None:
        described += ("\n          (python-can's slcan waits 2 s after every open; set "
                      "[sensor] sleep_after_open_s = 0 if your adapter needs no settle time)")
    return described
