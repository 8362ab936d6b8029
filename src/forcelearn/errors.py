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
     │    ├── PoseOutOfRange               a pose would pass the sensor's range; not moved there
     │    └── ToolMismatch                 free-space readings disagree with the calibrated tool
 ├── StudyError                        a study cannot run: folder conflict, cluster unreachable
     ├── PathError (ValueError)            a taught path cannot be used; nothing moved
     │    ├── PathParseError               a path file does not read (file, line, reason)
     │    └── PathRefused                  a path point breaks a limit (point, reason)
     ├── LinkError                         robot computer link
     │    ├── LinkTimeout (TimeoutError)   no ACK / reply within the timeout, retries spent
     │    ├── ProtocolError                a reply that breaks the link protocol
     │    │    └── EgmVersionMismatch      EGM datagrams of the other RobotWare egm.proto
     │    ├── RobotFault                   the controller answered with an error code
     │    ├── NotInPosition (TimeoutError) a move did not reach its target in time; stopped
     │    └── GuidanceStopped              the EGM controller is not (or no longer) guided
     ├── SensorError                       force/torque sensor
     │    ├── SensorTimeout (TimeoutError) no ACK from the sensor adapter
     │    ├── SensorStale                  no sample within the watchdog time
     │    │    └── SensorRebooted          the sensor rebooted: its zero is lost until re-tared
     │    ├── SensorBusError               the CAN bus or the sensor's network failed
     │    ├── SensorProtocolError          the sensor sent bytes or values its protocol forbids
     │    └── SensorFault                  the sensor reported an error in its status word
     └── SafetyStop                        a safety limit stopped the robot
          ├── ForceLimitExceeded           the contact force passed safety.max_force_n
          └── InvalidTarget (ValueError)   a commanded pose is malformed; nothing was sent
"""

from __future__ import annotations


def one_line(exc: BaseException) -> str:
    """The error's message, then each note a layer added (what to check), on one line."""
    return "; ".join([str(exc), *getattr(exc, "__notes__", ())])


class ForcelearnError(Exception):
    """Root of every error raised on purpose by forcelearn.

    A layer that knows what to check adds a note (``exc.add_note``) and lets
    the error go on with its type; :func:`one_line` shows both.
    """


class ConfigError(ForcelearnError, ValueError):
    """A configuration key or value is missing or out of range; the message names the key."""


class StateFileError(ForcelearnError):
    """A learned-state file cannot be read: damaged, truncated or of another format version."""


class RecordsFileError(StateFileError):
    """A run's records file (records.mcap) is missing or damaged; the message says what to do."""


class StudyError(ForcelearnError):
    """A study cannot run as asked: its folder holds another study, or the cluster is missing."""


class CalibrationError(ForcelearnError):
    """A calibration could not be made (poses ill-conditioned, a device failed midway)."""


class PoseOutOfRange(CalibrationError):
    """A pose's predicted reading would pass the sensor's range: the robot was not moved there."""


class ToolMismatch(CalibrationError):
    """Free-space readings disagree with the calibrated tool: run ``forcelearn calibrate``.

    The tool was changed, or the calibration is of another tool or sensor.
    """


class PathError(ForcelearnError, ValueError):
    """A taught path (CSV or RAPID module) cannot be used; it was refused before any move."""


class PathParseError(PathError):
    """A path file does not read: ``source`` and ``line`` (1-based, 0 if none) say where."""

    def __init__(self, source: str, line: int, reason: str) -> None:
        where = f"{source}:{line}" if line else source
        super().__init__(f"{where}: {reason}")
        self.source = source
        self.line = line
        self.reason = reason


class PathRefused(PathError):
    """A point of a taught path breaks a limit; ``index`` is 0-based, ``line`` its source line."""

    def __init__(self, index: int, name: str, line: int, reason: str) -> None:
        label = f"point {index + 1}" + (f" ({name})" if name else "")
        label += f" from line {line}" if line else ""
        super().__init__(f"path refused at {label}: {reason}")
        self.index = index
        self.name = name
        self.line = line
        self.reason = reason


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


class NotInPosition(LinkError, TimeoutError):
    """A commanded move was not reported in position within its time; the robot was stopped."""


class EgmVersionMismatch(ProtocolError):
    """EGM datagrams carry fields of the other RobotWare's ``egm.proto`` than the one configured.

    RW6 and RW7 differ on the wire (``EgmMeasuredForce.force`` is field 1 in RW6,
    field 2 in RW7): a parser built from the wrong file reads no force or a wrong
    one without failing. A subclass of :class:`ProtocolError` because the peer
    speaks another protocol version; its own class so the message can say which
    key to change (``robot.version``).
    """


class GuidanceStopped(LinkError):
    """The EGM controller does not follow the PC (motors, EGM or RAPID stopped; a restart).

    Motors off, EGM stopped or in error, RAPID stopped, or a new session
    (controller restart) dropped the target.

    Its own class because the link itself may be fine (datagrams still flow). After a
    comm timeout the shipped RAPID module (``rapid/ForcelearnEGM.modx``) opens a new session
    by itself and the run waits for it; motors off or a stopped RAPID program need the
    operator (the message says which).
    """


class SensorError(ForcelearnError):
    """Base of the force/torque sensor errors."""


class SensorTimeout(SensorError, TimeoutError):
    """The sensor adapter did not acknowledge a command in time."""


class SensorStale(SensorError):
    """No fresh sample arrived within the configured watchdog time."""


class SensorRebooted(SensorStale):
    """The sensor rebooted (JR3 bootup frame, Net F/T sequence restart): its zero is lost.

    After the first initialisation a driver never zeroes on its own: every read
    raises this until the cell has retracted to free space and called the
    driver's ``reinitialise()`` and re-tared (:func:`forcelearn.cell.retract_and_retare`).
    ``lost`` names what the reboot took (offsets, software bias...). A
    :class:`SensorStale` too, so a caller that stops on stale readings stops here.
    """

    def __init__(self, message: str, lost: str) -> None:
        super().__init__(message)
        self.lost = lost


class SensorSuspect(SensorError):
    """A reading in contact changed by more than the move can explain (a bias step?).

    The reading alone cannot tell a bias step from a force change; the cell
    can, by the move it made (:mod:`forcelearn.tasks.bias_watch`). The reading
    is not used: the run retracts, reads free space (the zero check), zeroes
    there and runs the trial again.
    """


class ZeroMoved(SensorSuspect):
    """Free space read off zero at a trial's end: the zero moved while the trial ran.

    A bias step the move could not show (smaller than the watch's margin, or in
    free space before the trial's first press) leaves every later reading of the
    trial off by the step. The trial is void: its readings are set aside
    (``voided.jsonl``), the learner and the map return to their state before it,
    the sensor is zeroed in free space and the trial runs again
    (``[task] zero_check``).
    """


class SensorBusError(SensorError):
    """The CAN bus, the sensor's network or their interface reported an error."""


class SensorProtocolError(SensorError):
    """The sensor sent bytes or values its protocol does not allow (e.g. zero counts per unit).

    A sensor error, not a :class:`ProtocolError` (which is the robot link's), so
    that ``except SensorError`` still catches every failure of the sensor path.
    """


class SensorFault(SensorError):
    """The sensor flagged an error in its status word; ``status`` is the raw word."""

    def __init__(self, status: int, reason: str) -> None:
        super().__init__(reason)
        self.status = status


class SafetyStop(ForcelearnError):
    """A safety limit (force, step, workspace, stale sensor) stopped the robot."""


class ForceLimitExceeded(SafetyStop):
    """The measured contact force passed the configured maximum; the robot retracts."""


class InvalidTarget(SafetyStop, ValueError):
    """A commanded pose is malformed (wrong length, not finite, non-unit quaternion).

    Nothing was sent. It is a :class:`SafetyStop`, so a caller guarding moves
    catches it, and a :class:`ValueError`, as every bad argument is.
    """
