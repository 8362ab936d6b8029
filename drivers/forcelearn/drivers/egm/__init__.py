"""ABB Externally Guided Motion (EGM) position guidance over UDP and protobuf.

Modules, one job each:

* ``proto``: ABB's ``egm.proto`` for RobotWare 6 and 7 and the generated modules.
* ``codec``: datagrams <-> plain values, version evidence from the wire (pure).
* ``config``: :class:`EgmConfig`, address, version, timing, bands and limits.
* ``guidance``: the session, seqno and ramp rules as pure state.
* ``driver``: :class:`EgmRobotDriver` (satisfies ``forcelearn.devices.Robot``)
  and :func:`open_egm_robot`.

The emulator imports only ``codec``; the driver classes load lazily here.
"""

from __future__ import annotations

import importlib
from typing import Any

_LAZY = {
    "EgmRobotDriver": "forcelearn.drivers.egm.driver",
    "EgmStatus": "forcelearn.drivers.egm.driver",
    "open_egm_robot": "forcelearn.drivers.egm.driver",
    "EgmConfig": "forcelearn.drivers.egm.config",
    "EgmStats": "forcelearn.drivers.egm.guidance",
}

__all__ = sorted(_LAZY)


def __getattr__(name: str) -> Any:
    if name in _LAZY:
        return getattr(importlib.import_module(_LAZY[name]), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
