"""Emulated ABB robot controller speaking the computer-link protocol (the kind ``computer_link``).

* ``controller``: protocol engine, frames in, answers out (no I/O).
* ``faults``: fault-injection hook.
* ``transport``: pty and loopback-TCP endpoints.
* ``server``: :class:`ComputerLinkEmulator`, the running emulator.

The arm it moves is :mod:`forcelearn.emulators.physics.arm`, every robot kind's.
Its old name, ``forcelearn.emulators.robot_controller``, imports for one release
with a DeprecationWarning.
"""

from forcelearn.emulators.computer_link.faults import ComputerLinkFaultConfig
from forcelearn.emulators.computer_link.server import ComputerLinkEmulator
from forcelearn.emulators.faults import Fault
from forcelearn.emulators.physics.arm import ArmConfig

__all__ = ["ArmConfig", "ComputerLinkEmulator", "ComputerLinkFaultConfig", "Fault"]
