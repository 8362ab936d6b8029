"""Emulated ATI Net F/T box on loopback: RDT over UDP, calibration over TCP and HTTP."""

from forcelearn.emulators.netft.faults import NetFtFaults
from forcelearn.emulators.netft.sensor_model import NetFtModelParams, NetFtSensorModel
from forcelearn.emulators.netft.server import NetFtEmulator, start_emulated_netft

__all__ = [
    "NetFtEmulator",
    "NetFtFaults",
    "NetFtModelParams",
    "NetFtSensorModel",
    "start_emulated_netft",
]
