"""JR3 force/torque sensor over the open JR3-to-CAN adapter protocol (python-can).

The protocol (opcode table, frame codec, count scaling) is
:mod:`forcelearn.protocols.jr3_can`, shared with the emulator. Here:
:mod:`.pairing` (counters), :mod:`.config`, :mod:`.listener` (bus frames ->
samples) and :mod:`.driver` (the sensor).
"""

from forcelearn.drivers.jr3_can.config import Jr3Config
from forcelearn.drivers.jr3_can.driver import Jr3CanSensor
from forcelearn.drivers.jr3_can.listener import Jr3Stats

__all__ = ["Jr3CanSensor", "Jr3Config", "Jr3Stats"]
