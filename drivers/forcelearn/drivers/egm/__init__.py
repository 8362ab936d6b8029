"""ABB Externally Guided Motion (EGM) position guidance over UDP and protobuf.

The datagrams (``egm.proto`` for RobotWare 6 and 7, the codec) are
:mod:`forcelearn.protocols.egm`, shared with the emulator. Here, one job per module:

* ``config``: :class:`EgmConfig`, address, version, timing, bands and limits.
* ``guidance``: the session, seqno and ramp rules as pure state.
* ``driver``: :class:`EgmRobot` (satisfies ``forcelearn.devices.Robot``)
  and :func:`open_egm_robot`.
"""

from forcelearn.deprecation import renamed
from forcelearn.drivers.egm.config import EgmConfig
from forcelearn.drivers.egm.driver import EgmRobot, EgmStatus, open_egm_robot
from forcelearn.drivers.egm.stats import EgmStats

__all__ = ["EgmConfig", "EgmRobot", "EgmStats", "EgmStatus", "open_egm_robot"]
__getattr__ = renamed(__name__, {"EgmRobotDriver": EgmRobot})
"""``EgmRobotDriver``: the old name of :class:`EgmRobot` (one release, with a warning)."""
