"""The one lifecycle every driver shares: construct, ``open()``, ``close()``; a context manager.

* **Construction** checks the configuration and takes the host's own
  resources (a serial port, a UDP socket, a CAN Notifier). If it fails, it
  releases what it took and raises; nothing is left to close.
* **open()** makes the device ready for its first command: reached,
  identified and initialised. It returns the driver and does nothing if the
  device is ready already, so ``with`` after an explicit ``open()`` repeats
  nothing. What "ready" takes per driver:

  ==================  ======================================  =============================
  driver              construction                            open() / entering ``with``
  ==================  ======================================  =============================
  ComputerLinkRobot   opens the port, identifies the          nothing more (re-opens the
                      controller, reads the target            port if a reconnect failed)
  EgmRobot            binds the UDP socket (``port`` known)   waits for the controller's
                                                              first EgmRobot (a session)
  Jr3CanSensor        starts the Notifier (async mode)        the host initialisation:
                                                              start, full scales, zero
  NetFtSensor         opens the UDP socket                    reads and checks the
                                                              calibration, bias, stream
  ==================  ======================================  =============================

* **Entering** ``with`` calls :meth:`Driver.open` through :func:`opened`:
  if opening fails, the driver is closed before the error goes on, so a
  missing device is reported at the ``with`` line, never at the first move
  or read in the middle of a run.
* **close()** brings the device to a safe rest, then releases the host's
  resources: a robot is stopped (computer link: STOP; EGM: the planned pose
  holds the measured one, then silence, which ends guidance after the
  controller's CommTimeout), a sensor stops streaming. Best effort (a device
  that does not answer is logged), idempotent and final: a closed driver
  raises its typed error (``LinkError`` for a robot, ``SensorError`` for a
  sensor) on ``open()`` and on every call.
* **Collected while open**: a ``ResourceWarning``, then :meth:`close` (the
  robot is stopped), as python-can does for a bus never shut down. At
  interpreter exit the driver is still closed, without the warning.
"""

from __future__ import annotations

import sys
import warnings
from typing import Self, TypeVar

from forcelearn.errors import ForcelearnError

D = TypeVar("D", bound="Driver")


class Driver:
    """Base of the drivers' lifecycle (see the module docstring).

    Subclasses set ``_acquired = True`` once construction holds resources and
    define the hooks :meth:`_is_ready`, :meth:`_make_ready`, :meth:`_release`
    and :meth:`_closed_error`.
    """

    _acquired = False
    _closed = False

    @property
    def closed(self) -> bool:
        """True once :meth:`close` has run."""
        return self._closed

    @property
    def ready(self) -> bool:
        """True while the device is open and ready for a command without reaching it first."""
        return not self._closed and self._is_ready()

    def open(self) -> Self:
        """Make the device ready for its first command (idempotent); return the driver.

        Raises:
            ForcelearnError: the driver's typed error: it is closed, or the
                device could not be reached or initialised.
        """
        if self._closed:
            raise self._closed_error()
        if not self._is_ready():
            self._make_ready()
        return self

    def close(self) -> None:
        """Bring the device to a safe rest and release the host's resources (idempotent)."""
        if self._closed:
            return
        self._closed = True
        if self._acquired:
            self._release()

    # ---- hooks ------------------------------------------------------------------------
    def _is_ready(self) -> bool:
        """True if the device needs nothing more before its first command."""
        raise NotImplementedError

    def _make_ready(self) -> None:
        """Reach, identify and initialise the device; raise the driver's typed error if not."""
        raise NotImplementedError

    def _release(self) -> None:
        """Stop the device (best effort) and release ports, sockets and threads."""
        raise NotImplementedError

    def _closed_error(self) -> ForcelearnError:
        """The error a call on a closed driver raises."""
        return ForcelearnError(f"this {type(self).__name__} is closed; create a new one")

    def _label(self) -> str:
        """The driver and its device, for the warning of one collected open."""
        return type(self).__name__

    # ---- protocol ---------------------------------------------------------------------
    def __enter__(self) -> Self:
        return opened(self)

    def __exit__(self, *exc_info: object) -> None:
        self.close()

    def __del__(self) -> None:
        if self._closed or not self._acquired:
            return
        # At interpreter exit module globals may already be None: a plain try keeps it quiet.
        try:
            if not sys.is_finalizing():
                warnings.warn(
                    f"{self._label()} was not closed: call close() or use it in a with block "
                    "(closing stops the device)",
                    ResourceWarning,
                    stacklevel=2,
                )
        except Exception:
            pass
        try:  # noqa: SIM105
            self.close()
        except Exception:
            pass


def opened(driver: D) -> D:
    """Open ``driver`` and return it; if opening fails, close it before the error goes on.

    What entering ``with`` does; the ``open_*`` factories return its result.
    """
    try:
        return driver.open()
    except BaseException:
        driver.close()
        raise
