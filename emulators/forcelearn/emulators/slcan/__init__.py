"""An emulated slcan (LAWICEL) USB-CAN adapter on a pseudo-terminal.

:mod:`forcelearn.protocols.lawicel` is the pure line codec, :mod:`.adapter` the adapter's rules,
:mod:`forcelearn.emulators.pty_endpoint` the serial side, :mod:`.server` the running emulator.
"""

from forcelearn.emulators.slcan.adapter import SlcanAdapterModel
from forcelearn.emulators.slcan.server import SlcanAdapterEmulator

__all__ = ["SlcanAdapterEmulator", "SlcanAdapterModel"]
