"""ABB computer-link position interface (the project's own ADLP-10-family protocol).

Modules, one job each:

* ``framing``: DLE STX ... DLE ETX + CRC-16 frames and DLE ACK/NAK/ENQ (pure).
* ``messages``: the application message set with 16-bit transaction numbers (pure).
* ``config``: :class:`LinkConfig`, serial settings, timeouts, retries and limits.
* ``link``: one request/reply transaction with the documented retries, over pyserial.
* ``driver``: :class:`ComputerLinkRobot`, which satisfies ``forcelearn.devices.Robot``.

The emulator imports only ``framing`` and ``messages``; the driver classes are
loaded lazily here so that importing the codec never pulls in pyserial.
"""

from __future__ import annotations

import importlib
from typing import Any

_LAZY = {
    "ComputerLinkRobot": "forcelearn.drivers.computer_link.driver",
    "LinkConfig": "forcelearn.drivers.computer_link.config",
    "Limits": "forcelearn.drivers.computer_link.config",
}

__all__ = sorted(_LAZY)


def __getattr__(name: str) -> Any:
    if name in _LAZY:
        return getattr(importlib.import_module(_LAZY[name]), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
