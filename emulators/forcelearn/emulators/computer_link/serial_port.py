"""``forcelearn-robot://``: a pyserial port whose far end is an in-process controller emulator.

``serial.serial_for_url("forcelearn-robot://NAME")`` attaches to the
:class:`~forcelearn.emulators.computer_link.server.ComputerLinkEmulator`
started in this process with ``transport="inproc"`` under NAME (its ``url``);
``forcelearn-robot://`` with no name starts a fresh emulator of its own (a
default arm, no shared physics, stopped when the port closes) whose serial
line costs the port's baud rate and framing in simulated time, and
``?instant=1`` makes its arm reach each target at once. What the driver writes
is answered in the writer's thread before ``write`` returns, so the link costs
no thread hand-over; ``read`` then returns the answer, and waits out its
timeout only when no answer is coming (a dropped reply, a stopped emulator),
as a real port would.

pyserial has no plugin registry: :func:`.url_scheme.register_url_handler` adds the handler
package to ``serial.protocol_handler_packages``. An in-process controller
emulator calls it when it starts, and the installed wheel's ``.pth`` hook
calls it at interpreter start, so ``forcelearn-robot://`` opens in a fresh
interpreter too (docs/emulators.md).
"""

from __future__ import annotations

import threading
import time
import urllib.parse
from typing import Any

from serial.serialutil import PortNotOpenError, SerialBase, SerialException

from forcelearn.emulators import registry
from forcelearn.emulators.clock import serial_char_time_s
from forcelearn.emulators.computer_link.url_scheme import REGISTRY_KIND, SCHEME
from forcelearn.protocols.computer_link import messages as m


class EmulatedRobotSerial(SerialBase):
    """A pyserial port on an in-process robot-controller emulator (``forcelearn-robot://``)."""

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        self._rx = bytearray()
        self._rx_lock = threading.RLock()
        self._cond = threading.Condition(self._rx_lock)
        """Waits and notifies on ``_cond``; ``with self._rx_lock`` holds it (one C call, where
        the condition's own ``with`` adds a Python frame each way: every frame passes here)."""
        self._hung_up = False
        self._emulator: Any = None
        self._owns_emulator = False
        super().__init__(*args, **kwargs)

    # ---- pyserial interface ---------------------------------------------------------
    def open(self) -> None:
        """Attach to the named emulator (or start a private one)."""
        if self.port is None:
            raise SerialException("Port must be configured before it can be used.")
        if self.is_open:
            raise SerialException("Port is already open.")
        name, instant = self._parse(str(self.port))
        emulator = self._find(name) if name else self._private(instant)
        try:
            emulator.connect(self)
        except BaseException as exc:
            if self._owns_emulator:
                emulator.close()
                self._owns_emulator = False
            if isinstance(exc, ConnectionError):
                raise SerialException(str(exc)) from exc
            raise
        with self._rx_lock:
            self._rx.clear()
            self._hung_up = False
        self._emulator = emulator
        self.is_open = True

    def _parse(self, url: str) -> tuple[str, bool]:
        parts = urllib.parse.urlsplit(url)
        if parts.scheme.lower() != SCHEME:
            raise SerialException(f"expected a {SCHEME}://NAME URL, got {url!r}")
        name = (parts.netloc + parts.path).strip("/")
        instant = False
        for key, values in urllib.parse.parse_qs(parts.query, keep_blank_values=True).items():
            if key != "instant" or values[-1] not in ("0", "1", ""):
                raise SerialException(
                    f"{url!r}: unknown option {key}={values[-1]!r}; the only option is "
                    "instant=0|1 (for a private emulator)"
                )
            instant = values[-1] != "0"
        if name and instant:
            raise SerialException(f"{url!r}: options apply to a private emulator (no NAME) only")
        return name, instant

    def _find(self, name: str) -> Any:
        emulator = registry.lookup(REGISTRY_KIND, name)
        if emulator is None:
            running = registry.names(REGISTRY_KIND) or ["none"]
            raise SerialException(
                f"no in-process robot controller emulator named {name!r} (running: "
                f"{', '.join(running)}); start ComputerLinkEmulator('inproc') in this "
                f"process and open its address, or open {SCHEME}:// for a private one"
            )
        return emulator

    def _private(self, instant: bool) -> Any:
        from forcelearn.emulators.computer_link.server import ComputerLinkEmulator
        from forcelearn.emulators.physics.arm import ArmConfig

        char_time = serial_char_time_s(self.baudrate, self.bytesize, self.parity,
                                       self.stopbits)
        emulator = ComputerLinkEmulator(
            "inproc", config=ArmConfig(instant=instant), char_time_s=char_time
        )
        emulator.start()
        self._owns_emulator = True
        return emulator

    def close(self) -> None:
        """Detach from the emulator (a private one stops); safe to call twice."""
        if self._emulator is not None:
            self._emulator.disconnect(self)
            if self._owns_emulator:
                self._emulator.close()
        self._emulator = None
        self._owns_emulator = False
        self.is_open = False

    def _reconfigure_port(self) -> None:
        """Settings take no effect on the wire (the emulator's line time is fixed at open)."""

    @property
    def in_waiting(self) -> int:
        """Bytes received and not read yet."""
        with self._rx_lock:
            return len(self._rx)

    def read(self, size: int = 1) -> bytes:
        """Up to ``size`` bytes: at once when the answer is in, else within ``timeout``."""
        if not self.is_open:
            raise PortNotOpenError()
        deadline = None if self.timeout is None else time.monotonic() + self.timeout
        with self._rx_lock:
            while len(self._rx) < size and not self._hung_up:
                left = None if deadline is None else deadline - time.monotonic()
                if left is not None and left <= 0:
                    break
                self._cond.wait(left)
            if self._hung_up and not self._rx:
                raise SerialException(
                    "device reports readiness to read but returned no data (the emulated "
                    "controller hung up): reopen the port"
                )
            data = bytes(self._rx[:size])
            del self._rx[:size]
        return data

    def write(self, data: bytes | bytearray | memoryview) -> int:  # type: ignore[override]
        """Hand ``data`` to the emulator, which answers before this returns."""
        if not self.is_open:
            raise PortNotOpenError()
        if self._hung_up:
            raise SerialException("write failed: the emulated controller hung up; reopen the port")
        payload = bytes(data)
        try:
            self._emulator.receive(self, payload)
        except ConnectionError as exc:
            raise SerialException(f"write failed: {exc}") from exc
        return len(payload)

    def carry_payload(self, payload: bytes) -> bytes | None:
        """The reply payload to a request payload, answered now; None: write its frame instead.

        The in-process route's short cut for :class:`~forcelearn.drivers.computer_link.link.Link`:
        what the controller would answer to the request's frame (and to the DLE ACK
        of its reply), with no frame built, checked or parsed on either side.
        """
        if not self.is_open:
            raise PortNotOpenError()
        if self._hung_up:
            raise SerialException("write failed: the emulated controller hung up; reopen the port")
        try:
            reply: bytes | None = self._emulator.carry(self, payload)
        except ConnectionError as exc:
            raise SerialException(f"write failed: {exc}") from exc
        return reply

    def carry_status(self, payload: bytes) -> m.Status | None:
        """:meth:`carry_payload` of a READ_STATUS request: the status its reply carries.

        None: carry or write it instead (``ComputerLinkEmulator.carry_status``).
        """
        if not self.is_open:
            raise PortNotOpenError()
        if self._hung_up:
            raise SerialException("write failed: the emulated controller hung up; reopen the port")
        try:
            status: m.Status | None = self._emulator.carry_status(self, payload)
        except ConnectionError as exc:
            raise SerialException(f"write failed: {exc}") from exc
        return status

    def flush(self) -> None:
        """Nothing is buffered on the way out."""

    def reset_input_buffer(self) -> None:
        """Discard received bytes."""
        with self._rx_lock:
            self._rx.clear()

    def reset_output_buffer(self) -> None:
        """Nothing is buffered on the way out."""

    # ---- the emulator's side --------------------------------------------------------
    def deliver(self, data: bytes) -> None:
        """Bytes from the controller (called by its endpoint)."""
        with self._rx_lock:
            self._rx += data
            self._cond.notify_all()

    def hang_up(self) -> None:
        """The controller dropped the connection."""
        with self._rx_lock:
            self._hung_up = True
            self._cond.notify_all()
