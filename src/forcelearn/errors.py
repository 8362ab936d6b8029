"""The one exception tree of forcelearn.

Every error the library raises on purpose derives from :class:`ForcelearnError`;
bad arguments raise the standard :class:`ValueError` (or :class:`ConfigError`,
which is both). Third-party errors (pyserial, python-can, OS) are converted at the
driver boundary with ``raise ... from``.

::

    ForcelearnError
     ├── ConfigError (ValueError)          a config key or value is wrong
     ├── StateFileError                    a learned-state file is damaged or of another version
     ├── CalibrationError                  a calibration could not be made; no file was written
     ├── LinkError                         robot computer link
     │    ├── LinkTimeout (TimeoutError)   no ACK / reply within the timeout, retries spent
     │    ├── ProtocolError                a reply that breaks the link protocol
     │    └── RobotFault                   the controller answered with an error code
     ├── SensorError                       force/torque sensor
     │    ├── SensorTimeout (TimeoutError) no ACK from the sensor adapter
     │    ├── SensorStale                  no sample within the watchdog time
     │    └── SensorBusError               the CAN bus itself failed
     └── SafetyStop                        a safety limit stopped the robot
          ├── ForceLimitExceeded           the contact force passed safety.max_force_n
          └── InvalidTarget (ValueError)   a commanded pose is malformed; nothing was sent
"""

from __future__ import annotations


class ForcelearnError(Exception):
    """Root of every error raised on purpose by forcelearn."""


class ConfigError(ForcelearnError, ValueError):
    """A configuration key or value is missing or out of range; the message names the key."""


class StateFileError(ForcelearnError):
    """A learned-state file cannot be read: damaged, truncated or of another format version."""


class CalibrationError(ForcelearnError):
    """A calibration could not be made (poses ill-conditioned, a device failed midway)."""


class LinkError(ForcelearnError):
    """Base of the robot computer-link errors."""


class LinkTimeout(LinkError, TimeoutError):
    """No acknowledgement or reply arrived in time, after the documented retries."""


class ProtocolError(LinkError):
    """The peer sent bytes or a message that the link protocol does not allow."""


class RobotFault(LinkError):
    """The robot controller refused a command; ``code`` is its error code."""

    def __init__(self, code: int, reason: str) -> None:
        super().__init__(f"robot controller error {code}: {reason}")
        self.code = code
        self.reason = reason


class SensorError(ForcelearnError):
    """Base of the force/torque sensor errors."""


class SensorTimeout(SensorError, TimeoutError):
    """The sensor adapter did not acknowledge a command in time."""


class SensorStale(SensorError):
    """No fresh sample arrived within the configured watchdog time."""


class SensorBusError(SensorError):
    """The CAN bus or its interface reported an error."""


class SafetyStop(ForcelearnError):
    """A safety limit (force, step, workspace, stale sensor) stopped the robot."""


class ForceLimitExceeded(SafetyStop):
    """The measured contact force passed the configured maximum; the robot retracts."""


class InvalidTarget(SafetyStop, ValueError):
    """A commanded pose is malformed (wrong length, not finite, non-unit quaternion).

    Nothing was sent. It is a :class:`SafetyStop`, so a caller guarding moves
    catches it, and a :class:`ValueError`, as every bad argument is.
    """
