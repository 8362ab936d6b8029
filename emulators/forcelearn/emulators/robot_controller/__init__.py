"""Deprecated: the computer link's emulator is :mod:`forcelearn.emulators.computer_link`.

One name per device (the kind ``computer_link``, its driver, protocol and
emulator). This package keeps the old imports working for one release, with a
:class:`DeprecationWarning`: its submodules are the new modules, and the old
class names give the new classes (``RobotControllerEmulator`` is
:class:`~forcelearn.emulators.computer_link.ComputerLinkEmulator`,
``FaultConfig`` :class:`~forcelearn.emulators.computer_link.ComputerLinkFaultConfig`).
"""

from __future__ import annotations

import importlib
import sys
import warnings

from forcelearn.deprecation import renamed
from forcelearn.emulators.computer_link import (
    ArmConfig,
    ComputerLinkEmulator,
    ComputerLinkFaultConfig,
    Fault,
)

NEW = "forcelearn.emulators.computer_link"
MODULES = {
    "controller": f"{NEW}.controller",
    "faults": f"{NEW}.faults",
    "kinematics": "forcelearn.emulators.physics.arm",
    "serial_port": f"{NEW}.serial_port",
    "server": f"{NEW}.server",
    "transport": f"{NEW}.transport",
    "url_scheme": f"{NEW}.url_scheme",
}
"""Old submodule -> the module that replaced it (imported under both names)."""

warnings.warn(f"{__name__} is deprecated: import {NEW} (the old name goes in the next release)",
              DeprecationWarning, stacklevel=2)
for _old, _new in MODULES.items():
    sys.modules[f"{__name__}.{_old}"] = importlib.import_module(_new)

__all__ = ["ArmConfig", "Fault"]
__getattr__ = renamed(__name__, {"RobotControllerEmulator": ComputerLinkEmulator,
                                 "FaultConfig": ComputerLinkFaultConfig})
