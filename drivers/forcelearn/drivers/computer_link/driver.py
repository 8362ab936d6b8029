"""ABB robot over the computer link: a ``forcelearn.devices.Robot`` driven through pyserial.

::

    with ComputerLinkRobot(LinkConfig(url="/dev/ttyS0", baudrate=19200)) as robot:
        robot.move_to(robot.read_pose().moved(dz_mm=-1.0))

Every call blocks for at most the documented retries times the configured
timeouts and raises typed errors: ``SafetyStop`` (a client-side limit refused
the command, nothing was sent), ``RobotFault`` (the controller refused, with
its code), ``LinkTimeout``, ``ProtocolError`` or ``LinkError``. Calls are
serialised by a lock, so several threads may share one driver. The driver is
ready once constructed (the port is open and the controller identified), so
entering ``with`` adds nothing; leaving it (or :meth:`close`) stops the robot
and closes the port (:mod:`forcelearn.drivers.lifecycle`).

A move returns when the controller has *accepted* it; :meth:`wait_in_position`
then polls READ_STATUS back to back (each poll costs its bytes' time on the
line, ~35 ms at 9600 baud) until the robot reports in position, and holds
there for a settle time. Both are measured on the controller's clock (the
status reply carries it), so a wait lasts the same on a real and an emulated
cell; a wall-clock guard ends a wait on a controller whose clock stands still.

The reference for relative moves and for the step limit is always the
target the controller will apply (READ_TARGET after opening, a stop, a
reconnect or any link error), never a pose the robot has merely reached.
"""

from __future__ import annotations

import logging
import math
import threading
import time

import numpy as np
import serial

from forcelearn.devices import InPositionWait, Pose
from forcelearn.drivers.computer_link.config import POLL_S, LinkConfig
from forcelearn.drivers.computer_link.link import PORT_ERRORS, Link
from forcelearn.drivers.lifecycle import Driver
from forcelearn.drivers.targets import unit_quaternion
from forcelearn.errors import (
    ForcelearnError,
    LinkError,
    NotInPosition,
    SafetyStop,
)
from forcelearn.protocols.computer_link import messages as m

log = logging.getLogger(__name__)


class ComputerLinkRobot(Driver):
    """Driver of one robot controller on one serial link (satisfies ``Robot``).

    Opening the link identifies the controller (``ProtocolError`` if it speaks
    another protocol version) and reads the pose, which becomes the reference
    for the step limit.
    """

    def __init__(self, config: LinkConfig) -> None:
        self.config = config
        self._lock = threading.RLock()
        self._port: serial.SerialBase | None = None
        self._link: Link | None = None
        self._reference: Pose | None = None
        self.controller_model = ""
        self.last_wait: InPositionWait | None = None
        """How the last :meth:`wait_in_position` ended (no pose: reading it costs an exchange)."""
        self._open()
        self._acquired = True

    def _open(self) -> None:
        cfg = self.config
        try:
            self._port = serial.serial_for_url(
                cfg.url,
                baudrate=cfg.baudrate,
                bytesize=cfg.bytesize,
                parity=cfg.parity,
                stopbits=cfg.stopbits,
                timeout=min(POLL_S, cfg.ack_timeout_s),
                write_timeout=cfg.ack_timeout_s,
            )
        except (serial.SerialException, OSError) as exc:
            raise LinkError(f"cannot open robot link {cfg.url}: {exc}") from exc
        self._link = Link(self._port, cfg)
        try:
            _, self.controller_model = self._link.probe_protocol()
            self._reference = self._read_target_locked()
        except ForcelearnError:
            self._close_port()
            raise
        log.info("robot link open on %s: %s", cfg.url, self.controller_model)

    def reconnect(self) -> None:
        """Close the port and open it again (after a LinkError); the reference is re-read.

        The reference becomes the controller's commanded target (READ_TARGET),
        so a relative move after a lost link adds to what the controller will
        apply, never to where the robot happened to be.
        """
        with self._lock:
            if self.closed:
                raise self._closed_error()
            self._close_port()
            self._open()

    def _require_link(self) -> Link:
        if self._link is None:
            raise self._closed_error() if self.closed else LinkError(
                f"robot link on {self.config.url} is not open (a reconnect failed): call "
                "reconnect() or open()"
            )
        return self._link

    # -- reading ---------------------------------------------------------------------------

    def _read_position_locked(self) -> tuple[Pose, tuple[float, ...]]:
        reply = self._require_link().transact(m.Command.READ_POSITION)
        position = m.parse_position(reply.body)
        return Pose(*position.xyz_mm, position.quaternion), position.joints_deg

    def read_pose(self) -> Pose:
        """Return the pose the robot is at now (mm, quaternion w x y z)."""
        with self._lock:
            return self._read_position_locked()[0]

    def read_joints_deg(self) -> tuple[float, ...]:
        """Return the six joint angles in degrees."""
        with self._lock:
            return self._read_position_locked()[1]

    def read_status(self) -> m.Status:
        """Return moving / in-position flags, last error, move count and controller time (s)."""
        with self._lock:
            return self._require_link().read_status()

    def _read_target_locked(self) -> Pose:
        xyz, quaternion = m.parse_pose(self._require_link().transact(m.Command.READ_TARGET).body)
        return Pose(*xyz, quaternion)

    def read_target(self) -> Pose:
        """Return the target the controller is moving to (mm, quaternion w x y z)."""
        with self._lock:
            self._reference = self._read_target_locked()
            return self._reference

    def wait_in_position(self, timeout_s: float, settle_s: float = 0.0) -> float:
        """Poll until the robot is in position and has stayed so for ``settle_s``.

        Both times are on the controller's clock. Returns the controller time
        (s) at the end of the wait.

        Raises:
            NotInPosition: not in position (and settled) within ``timeout_s``
                of controller time; the robot has been stopped.
        """
        if not (math.isfinite(timeout_s) and timeout_s > 0 and settle_s >= 0):
            raise ValueError(f"need timeout_s > 0 and settle_s >= 0, got {timeout_s}, {settle_s}")
        with self._lock:
            wall_limit = time.monotonic() + timeout_s + 10.0
            first = status = self.read_status()
            since: float | None = None
            previous = math.nan
            while True:
                if status.in_position and not status.moving:
                    since = status.time_s if since is None else since
                    if status.time_s - since >= settle_s or status.time_s == previous:
                        # settled; or a clock that stands still (an emulated cell where
                        # nothing takes time): dwelling could change nothing
                        self.last_wait = InPositionWait(since, None)
                        return status.time_s
                else:
                    since = None
                previous = status.time_s
                waited = status.time_s - first.time_s
                if waited > timeout_s or time.monotonic() > wall_limit:
                    self._stop_after_timeout()
                    raise NotInPosition(
                        f"the robot did not report in position within {timeout_s} s "
                        f"(waited {waited:.3f} s of controller time, {status}); it was "
                        "stopped: check the speed, the in-position band, obstacles and "
                        "robot.move_timeout_s"
                    )
                status = self.read_status()

    def _stop_after_timeout(self) -> None:
        try:
            self.stop()
        except ForcelearnError as exc:
            log.error("could not stop the robot after a move timed out: %s", exc)

    # -- commanding ------------------------------------------------------------------------

    def move_to(self, pose: Pose) -> None:
        """Move to an absolute pose; returns when the controller has accepted it.

        Raises:
            InvalidTarget: the quaternion is not 4 finite numbers of unit length.
            SafetyStop: the target breaks a limit. In both cases nothing was sent.
        """
        unit_quaternion(pose.quaternion, "pose quaternion")
        with self._lock:
            self._check_target(pose)  # before packing: huge values are refused, not overflowed
            body = m.pose_body((pose.x_mm, pose.y_mm, pose.z_mm), pose.quaternion)
            self._command(m.Command.MOVE_TO, body, pose)

    def move_by(self, dx_mm: float = 0.0, dy_mm: float = 0.0, dz_mm: float = 0.0) -> None:
        """Move by an increment from the last commanded position, orientation kept."""
        with self._lock:
            reference = self._reference_locked()
            target = reference.moved(dx_mm, dy_mm, dz_mm)
            self._check_target(target)
            self._command(m.Command.MOVE_BY, m.increment_body((dx_mm, dy_mm, dz_mm)), target)

    def set_speed(self, speed_mm_s: float) -> None:
        """Set the speed of later moves, mm/s (refused above ``limits.max_speed_mm_s``)."""
        limit = self.config.limits.max_speed_mm_s
        if not (math.isfinite(speed_mm_s) and 0 < speed_mm_s <= limit):
            raise SafetyStop(
                f"refused speed {speed_mm_s} mm/s: allowed 0..{limit} (limits.max_speed_mm_s); "
                "nothing was sent"
            )
        with self._lock:
            self._require_link().transact(m.Command.SET_SPEED, m.speed_body(speed_mm_s))

    def stop(self) -> None:
        """Stop all motion at once (the controller brakes; its rest point is the new target)."""
        with self._lock:
            self._reference = None  # re-read from the controller before the next move
            self._require_link().transact(m.Command.STOP)

    def _reference_locked(self) -> Pose:
        if self._reference is None:
            self._reference = self._read_target_locked()
        return self._reference

    def _check_target(self, target: Pose) -> None:
        """Raise SafetyStop if ``target`` breaks a client-side limit (nothing is sent)."""
        limits = self.config.limits
        # floats, not arrays (every move): the same comparisons, and the step by the float
        # operations of numpy.linalg.norm of the difference (three squares in order, the root)
        position = (float(target.x_mm), float(target.y_mm), float(target.z_mm))
        low, high = limits.workspace_min_mm, limits.workspace_max_mm
        if not all(math.isfinite(c) and lo <= c <= hi
                   for c, lo, hi in zip(position, low, high, strict=True)):
            raise SafetyStop(
                f"refused target {np.round(position, 3).tolist()} mm: outside the workspace box "
                f"{np.asarray(low).tolist()}..{np.asarray(high).tolist()}"
                " (limits.workspace_*_mm); nothing was sent"
            )
        reference = self._reference_locked()
        dx, dy, dz = (position[0] - float(reference.x_mm), position[1] - float(reference.y_mm),
                      position[2] - float(reference.z_mm))
        step = math.sqrt(dx * dx + dy * dy + dz * dz)
        if not step <= limits.max_step_mm:  # NaN (a non-finite reported pose) is refused too
            raise SafetyStop(
                f"refused a step of {step:.3f} mm: more than limits.max_step_mm = "
                f"{limits.max_step_mm} mm; nothing was sent"
            )

    def _command(self, command: m.Command, body: bytes, target: Pose) -> None:
        try:
            self._require_link().transact(command, body)
        except LinkError:
            self._reference = None  # accepted or not: READ_TARGET tells before the next move
            raise
        self._reference = target

    # -- lifetime (forcelearn.drivers.lifecycle) -------------------------------------------

    def _is_ready(self) -> bool:
        return self._link is not None

    def _make_ready(self) -> None:
        with self._lock:
            self._open()

    def _release(self) -> None:
        """Stop the robot (best effort) and close the port."""
        with self._lock:
            try:
                if self._link is not None:
                    self.stop()
            except ForcelearnError as exc:
                log.warning("could not stop the robot while closing the link: %s", exc)
            finally:
                self._close_port()

    def _closed_error(self) -> LinkError:
        return LinkError(f"the robot link on {self.config.url} is closed; open a new "
                         "ComputerLinkRobot")

    def _label(self) -> str:
        return f"ComputerLinkRobot on {self.config.url}"

    def _close_port(self) -> None:
        self._link = None
        if self._port is not None:
            try:
                self._port.close()
            except PORT_ERRORS as exc:
                log.warning("closing %s failed: %s", self.config.url, exc)
            self._port = None
