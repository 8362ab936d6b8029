"""Emulated JR3-to-CAN adapter: a bus node over the shared physics and a sensor model.

``FaultConfig``, ``SensorModel`` and ``SensorModelParams`` are the old names of
:class:`Jr3FaultConfig`, :class:`Jr3SensorModel` and :class:`Jr3ModelParams`
(importable for one release, with a DeprecationWarning).
"""

from forcelearn.deprecation import renamed
from forcelearn.emulators.jr3.faults import Jr3FaultConfig
from forcelearn.emulators.jr3.node import Jr3EmulatorNode
from forcelearn.emulators.jr3.sensor_model import Jr3ModelParams, Jr3SensorModel

__all__ = ["Jr3EmulatorNode", "Jr3FaultConfig", "Jr3ModelParams", "Jr3SensorModel"]
__getattr__ = renamed(__name__, {"FaultConfig": Jr3FaultConfig, "SensorModel": Jr3SensorModel,
                                 "SensorModelParams": Jr3ModelParams})
