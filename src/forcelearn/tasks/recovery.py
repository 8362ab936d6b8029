"""Leave the part, then re-zero: what the cell does after a device fault in contact.

When a reading cannot be trusted (a sensor that rebooted, went silent or sent
damage) or a move did not end as commanded (a controller restart, a link
dropped, a move that never reached its target), the tool may be pressing the
part. Nothing else happens before it leaves:

1. the robot is stopped;
2. it retracts along the force axis (+Y) to the task's retract plane (or where
   the task's ``away`` says: the path task's force axis), from where it *is* (the
   pose is read again), in limited steps and without reading
   the sensor (its readings are what is in doubt); a link that dropped is
   reconnected first, if the driver can (``reconnect()``), and a controller
   that stopped guiding (EGM after its CommTimeout: the session dropped) is
   waited for until its RAPID program opens a new session
   (``wait_for_guidance()``, up to :data:`GUIDANCE_WAIT_S`);
3. in free space the sensor is started again without zeroing (a rebooted one
   reads its raw bias) and zeroed there (:meth:`~forcelearn.cell.Cell.zero_in_free_space`),
   which also re-derives the calibration's bias for this pose.

Each stage is tried up to ``attempts`` times (a link or a sensor that comes
back within them is used again); when a stage still fails,
:class:`RecoveryFailed` says which and whether the tool may still be in contact.
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from dataclasses import dataclass

from forcelearn.cell import Cell
from forcelearn.devices import Pose
from forcelearn.errors import (
    ForcelearnError,
    ForceLimitExceeded,
    GuidanceStopped,
    InvalidTarget,
    LinkError,
    SafetyStop,
    SensorError,
)

log = logging.getLogger(__name__)

RECOVERABLE: tuple[type[ForcelearnError], ...] = (LinkError, SensorError)
"""Device errors after which the cell retracts, re-zeroes and the run goes on."""

ATTEMPTS = 3
"""Tries of the retract before the recovery gives up."""

GUIDANCE_WAIT_S = 10.0
"""Longest wait for a controller that stopped guiding to open a new session, s of its time
(rapid/ForcelearnEGM.modx re-opens it 1 s after its 1 s CommTimeout; a link down longer
stops it again each time until the link is back)."""

ZERO_ATTEMPTS = 5
"""Tries of the sensor's restart and zero (each bounded by its ACK or stale timeout)."""


class RecoveryFailed(SafetyStop):
    """The cell could not retract or re-zero after a fault; ``in_contact`` if it did not retract."""

    def __init__(self, message: str, in_contact: bool) -> None:
        super().__init__(message)
        self.in_contact = in_contact


def recoverable(exc: BaseException) -> bool:
    """True for a device fault the cell recovers from (not a limit, a bad target or a config)."""
    return isinstance(exc, RECOVERABLE) and not isinstance(exc, (InvalidTarget, ForceLimitExceeded))


@dataclass(frozen=True)
class Recovered:
    """What a recovery did: where it retracted to, what free space read before the zero."""

    retract_pose: Pose
    """The pose the tool retracted to (free space), mm."""
    free_reading_n: float
    """The normal force read in free space just before zeroing, N (the raw bias after a reboot)."""
    retract_tries: int
    """Tries the retract took."""
    zero_tries: int
    """Tries the re-zero took."""


AwayFrom = Callable[[Pose], Pose]
"""The free-space pose to retract to from the pose the tool is at (a task's force axis)."""


def retract(cell: Cell, retract_y_mm: float, max_step_mm: float,
            attempts: int = ATTEMPTS, away: AwayFrom | None = None) -> tuple[Pose, int]:
    """Stop, then move along +Y to ``retract_y_mm`` without reading the sensor; (pose, tries).

    ``away``: where to retract to from the pose read instead (the path task: back along
    its force axis); None: +Y to the §5 task's retract plane.

    Raises:
        RecoveryFailed: the robot did not retract in ``attempts`` tries (``in_contact``).
    """
    cell.stop()
    last: ForcelearnError | None = None
    for attempt in range(1, attempts + 1):
        try:
            if _reconnect_if_down(cell):
                cell.stop()  # the stop before went nowhere: the controller may still move
            here = cell.read_pose()
            target = (away(here) if away is not None else
                      Pose(here.x_mm, max(here.y_mm, retract_y_mm), here.z_mm, here.quaternion))
            cell.move_in_steps(target, max_step_mm)
            return target, attempt
        except (LinkError, SensorError, SafetyStop) as exc:  # a refused step: stop, plan again
            last = exc
            log.warning("retract try %d of %d failed: %s", attempt, attempts, exc)
            cell.stop()
            if isinstance(exc, GuidanceStopped):
                _wait_for_guidance(cell)
    where, jog = ((f"to y = {retract_y_mm} mm", "jog +Y") if away is None else
                  ("back along the task's force axis", "jog it back along the tool's axis"))
    raise RecoveryFailed(
        f"could not retract the tool {where} after a fault ({attempts} tries; "
        f"last: {last}): the tool may still press the part; retract it by hand ({jog}), "
        "check the robot link, then resume the run (it retracts first)",
        in_contact=True,
    ) from last


def rezero(cell: Cell, attempts: int = ZERO_ATTEMPTS) -> tuple[float, int]:
    """Start the sensor again and zero it here (free space); (reading before the zero, tries).

    Raises:
        RecoveryFailed: the sensor did not answer in ``attempts`` tries (tool in free space).
    """
    last: ForcelearnError | None = None
    for attempt in range(1, attempts + 1):
        try:
            return cell.zero_in_free_space(), attempt
        except SensorError as exc:
            last = exc
            log.warning("re-zero try %d of %d failed: %s", attempt, attempts, exc)
    raise RecoveryFailed(
        f"the sensor did not come back after a fault ({attempts} tries; last: {last}): the "
        "tool is retracted in free space; check the sensor's power and cable, then resume "
        "the run",
        in_contact=False,
    ) from last


def retract_and_retare(cell: Cell, retract_y_mm: float, max_step_mm: float,
                       attempts: int = ATTEMPTS, away: AwayFrom | None = None) -> Recovered:
    """Retract to free space, then start the sensor again and zero it (the module docstring).

    ``away``: as :func:`retract`'s.

    Raises:
        RecoveryFailed: a stage failed ``attempts`` times; ``in_contact`` says which.
    """
    pose, retract_tries = retract(cell, retract_y_mm, max_step_mm, attempts, away)
    reading, zero_tries = rezero(cell, max(attempts, ZERO_ATTEMPTS))
    log.warning("recovered: retracted to (%.1f, %.1f, %.1f) mm, re-zeroed (free space read "
                "%.2f N)", pose.x_mm, pose.y_mm, pose.z_mm, reading)
    return Recovered(pose, reading, retract_tries, zero_tries)


def _wait_for_guidance(cell: Cell) -> None:
    """Wait for a controller that stopped guiding to guide again (a driver that can say so)."""
    wait = getattr(cell.robot, "wait_for_guidance", None)
    if wait is None:
        return
    try:
        wait(GUIDANCE_WAIT_S)
        log.warning("the controller guides again (a new session): retracting")
    except ForcelearnError as exc:
        log.warning("the controller did not guide again: %s", exc)


def _reconnect_if_down(cell: Cell) -> bool:
    """Reopen a robot link that reports itself down (a driver with ``reconnect()``); True if so."""
    reconnect = getattr(cell.robot, "reconnect", None)
    if reconnect is None:
        return False
    try:
        cell.robot.read_pose()
        return False
    except LinkError:
        reconnect()
        return True

