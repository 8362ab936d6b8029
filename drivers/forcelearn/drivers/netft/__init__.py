"""ATI Net F/T force/torque sensor over Ethernet: RDT over UDP, calibration over TCP or HTTP.

Layers: :mod:`forcelearn.protocols.netft` (the pure wire formats, shared with the
emulator), :mod:`.calibration` (counts per
unit from the box, checked), :mod:`.sequence` (lost/duplicate/out-of-order
accounting), :mod:`.traffic_log`, :mod:`.config` and :mod:`.driver` (the sensor).
"""

from forcelearn.drivers.netft.config import NetFtConfig
from forcelearn.drivers.netft.driver import NetFtSensor, NetFtStats, open_netft_sensor

__all__ = ["NetFtConfig", "NetFtSensor", "NetFtStats", "open_netft_sensor"]
