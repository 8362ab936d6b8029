"""``forcelearn check`` for the Ethernet devices: an EGM robot and an ATI Net F/T box.

Called by :mod:`.check_command` for ``[robot] kind = "egm"`` and ``[sensor]
kind = "netft"``. Neither ever moves the robot:

* **EGM**: the driver answers the controller with the pose it reports (a
  hold) and nothing else; the check reads the session (version, feedback
  pose, motor/EGM/RAPID states, controller time, traffic counters) and fails
  if the driver's target ever differs from the session's start pose, or if
  the controller is not guided (motors off, EGM or RAPID stopped).
* **Net F/T**: the calibration the box reports (counts per unit, units, RDT
  rate, filter, ranges), records for ``seconds`` (rate achieved against the
  box's RDT rate; lost, duplicated, out-of-order, rejected datagrams and
  reboots, which should all be 0), mean and noise per axis, the normal force.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import Any

import numpy as np

from forcelearn.devices import AXES
from forcelearn.drivers.egm import EgmRobotDriver
from forcelearn.drivers.netft import NetFtSensor
from forcelearn.errors import SafetyStop
from forcelearn.site.config import CellConfig

UNITS = ("N", "N", "N", "N*m", "N*m", "N*m")
BATCH = 64
"""Records per read_many call while sampling (one burst request)."""

Printer = Callable[[str], None]


def check_egm(robot: EgmRobotDriver, say: Printer) -> Any:
    """Report the EGM session; return a token for :func:`check_egm_unmoved`."""
    config = robot.config
    pose = robot.read_pose()
    status = robot.read_status()
    say(f"  robot   EGM session ({config.version}) on UDP {config.host}:{robot.port}: "
        f"motors {status.motor.name}, EGM {status.mci.name}, RAPID {status.rapid.name}, "
        f"controller time {status.controller_time_s:.3f} s")
    say(f"  robot   pose x {pose.x_mm:.2f}  y {pose.y_mm:.2f}  z {pose.z_mm:.2f} mm, "
        f"quaternion (w x y z) {' '.join(f'{q:.4f}' for q in pose.quaternion)}")
    stats = status.stats
    say(f"  robot   {stats.received} EgmRobot received, {stats.replies} answers (holds), "
        f"missed {stats.missed}, duplicates {stats.duplicates}, out of order "
        f"{stats.out_of_order}, unreadable {stats.bad_datagrams}")
    say(f"  robot   paired with the controller at {robot.controller_address}; ignored: "
        f"{stats.foreign_datagrams} from other hosts, {stats.wrong_version} of the other "
        f"RobotWare, {stats.seqno_jumps} seqno jumps, {stats.replays} replayed starts, "
        f"{stats.refused_sessions} refused session starts")
    robot.read_target()  # raises GuidanceStopped if the controller is not guided
    return robot.target


def check_egm_unmoved(robot: EgmRobotDriver, before: Any, say: Printer) -> None:
    """Fail if the driver's target changed during the check (it must only hold)."""
    after = robot.target
    if after != before:
        raise SafetyStop(
            f"the EGM target changed from {before} to {after} during the check: "
            "something in this process commanded the robot"
        )
    status = robot.read_status()
    say(f"  robot   still guided: EGM {status.mci.name}, RAPID {status.rapid.name}; "
        "no target was sent other than the pose it reported")


def check_netft(sensor: NetFtSensor, config: CellConfig, seconds: float, say: Printer) -> None:
    """Report the box's calibration, a few seconds of records and the counts of faults."""
    cal = sensor.calibration
    if cal is not None:
        rate = f"{cal.rdt_rate_hz:g} Hz" if cal.rdt_rate_hz else "not reported (TCP)"
        filt = cal.filter_index if cal.filter_index is not None else "not reported"
        say(f"  sensor  Net F/T at {sensor.config.host}: calibration over {cal.source}: "
            f"{cal.counts_per_force:g} counts/{cal.force_unit}, {cal.counts_per_torque:g} "
            f"counts/{cal.torque_unit}; RDT rate {rate}; filter {filt}")
        if cal.ranges_si is not None:
            say(f"  sensor  ranges {' '.join(f'{r:g}' for r in cal.ranges_si[:3])} N, "
                f"{' '.join(f'{r:g}' for r in cal.ranges_si[3:])} N*m")
    before = sensor.stats
    samples = []
    start = time.monotonic()
    while time.monotonic() - start < seconds:
        samples += sensor.read_many(BATCH)
    elapsed = time.monotonic() - start
    stats = sensor.stats
    rate_note = ""
    if cal is not None and cal.rdt_rate_hz:
        rate_note = f" (the box streams at up to {cal.rdt_rate_hz:g}/s)"
    say(f"  sensor  {len(samples)} records in {elapsed:.2f} s: {len(samples) / elapsed:.0f} "
        f"records/s{rate_note}; lost {stats.lost - before.lost}, duplicates "
        f"{stats.duplicates - before.duplicates}, out of order "
        f"{stats.out_of_order - before.out_of_order}, rejected "
        f"{stats.rejected_total - before.rejected_total}, reboots "
        f"{stats.reboots - before.reboots}")
    wrench = np.array([s.wrench for s in samples])
    mean, noise = wrench.mean(axis=0), wrench.std(axis=0)
    say("          axis        mean   noise (std)")
    for name, unit, m, n in zip(AXES, UNITS, mean, noise, strict=True):
        say(f"          {name}  {m:>+10.3f}  {n:>10.3f}  {unit}")
    axis, sign = config.filter.axis, config.filter.sign
    say(f"  sensor  normal force ({'+' if sign > 0 else '-'}{AXES[axis]}, [filter] axis "
        f"{axis}): mean {sign * mean[axis]:+.3f} N, noise {noise[axis]:.3f} N")


def describe_egm(config: CellConfig) -> str:
    """The ``robot`` line of the check's header for an EGM robot."""
    if config.robot_emulated:
        return "built-in EGM controller emulator on loopback UDP (lockstep)"
    robot = config.robot
    return (f"EGM {robot.version}: listening on UDP {robot.host}:{robot.port} for the "  # type: ignore[union-attr]
            "controller (start the ForcelearnEGM RAPID program)")


def describe_netft(config: CellConfig) -> str:
    """The ``sensor`` line of the check's header for a Net F/T box."""
    if config.sensor_emulated:
        return "built-in Net F/T emulator on loopback (RDT UDP, READCALINFO TCP, HTTP)"
    s = config.sensor
    return (f"Net F/T at {s.host}: RDT UDP {s.rdt_port}, calibration over "  # type: ignore[union-attr]
            f"{s.calibration_source}")  # type: ignore[union-attr]
