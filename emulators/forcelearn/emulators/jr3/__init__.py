"""Emulated JR3-to-CAN adapter: a bus node over the shared physics and a sensor model."""

from forcelearn.emulators.jr3.faults import FaultConfig
from forcelearn.emulators.jr3.node import Jr3EmulatorNode
from forcelearn.emulators.jr3.sensor_model import SensorModel, SensorModelParams

__all__ = ["FaultConfig", "Jr3EmulatorNode", "SensorModel", "SensorModelParams"]
