"""ABB computer-link position interface (the project's own ADLP-10-family protocol).

The protocol itself (frames and messages) is :mod:`forcelearn.protocols.computer_link`,
shared with the emulator. Here, one job per module:

* ``config``: :class:`LinkConfig`, serial settings, timeouts, retries and limits.
* ``link``: one request/reply transaction with the documented retries, over pyserial.
* ``driver``: :class:`ComputerLinkRobot`, which satisfies ``forcelearn.devices.Robot``.
"""

from forcelearn.drivers.computer_link.config import LinkConfig
from forcelearn.drivers.computer_link.driver import ComputerLinkRobot
from forcelearn.drivers.limits import Limits

__all__ = ["ComputerLinkRobot", "Limits", "LinkConfig"]
