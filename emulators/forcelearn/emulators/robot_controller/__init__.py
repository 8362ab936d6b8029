"""Emulated ABB robot controller speaking the computer-link protocol.

* ``kinematics``: arm limits and the Cartesian servo (pure).
* ``controller``: protocol engine, frames in, answers out (no I/O).
* ``faults``: fault-injection hook.
* ``transport``: pty and loopback-TCP endpoints.
* ``server``: :class:`RobotControllerEmulator`, the running emulator.
"""

from forcelearn.emulators.robot_controller.faults import Fault, FaultConfig
from forcelearn.emulators.robot_controller.kinematics import ArmConfig
from forcelearn.emulators.robot_controller.server import RobotControllerEmulator

__all__ = ["ArmConfig", "Fault", "FaultConfig", "RobotControllerEmulator"]
