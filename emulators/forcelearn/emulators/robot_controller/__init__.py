"""Emulated ABB robot controller speaking the computer-link protocol.

* ``kinematics``: the old home of the arm (:mod:`forcelearn.emulators.physics.arm`).
* ``controller``: protocol engine, frames in, answers out (no I/O).
* ``faults``: fault-injection hook.
* ``transport``: pty and loopback-TCP endpoints.
* ``server``: :class:`RobotControllerEmulator`, the running emulator.
"""

from forcelearn.emulators.faults import Fault
from forcelearn.emulators.physics.arm import ArmConfig
from forcelearn.emulators.robot_controller.faults import FaultConfig
from forcelearn.emulators.robot_controller.server import RobotControllerEmulator

__all__ = ["ArmConfig", "Fault", "FaultConfig", "RobotControllerEmulator"]
