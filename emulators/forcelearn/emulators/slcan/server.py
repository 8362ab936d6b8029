"""An emulated slcan (LAWICEL) USB-CAN adapter: a pty on one side, a CAN bus on the other.

A host opens :attr:`SlcanAdapterEmulator.address` exactly as it would the serial
port of a CANable-style adapter, e.g. with python-can::

    with SlcanAdapterEmulator(channel="jr3") as adapter:
        node = Jr3EmulatorNode(physics, channel="jr3")
        bus = can.Bus(interface="slcan", channel=adapter.address, bitrate=1_000_000)

One thread reads host lines from the pty and answers them
(:mod:`.lawicel` parses, :mod:`.adapter` decides); frames for the bus go out
on the python-can bus. A ``can.Notifier`` thread passes frames heard on the
bus to the host. ``stop()`` ends both and releases the pty.
"""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Callable

import can

from forcelearn.emulators.lifecycle import Emulator
from forcelearn.emulators.pty_endpoint import PtyEndpoint
from forcelearn.emulators.slcan.adapter import FLAG_BUS_ERROR, SlcanAdapterModel
from forcelearn.protocols.lawicel import CanFrame, LineSplitter, parse_line

log = logging.getLogger(__name__)

POLL_S = 0.02
"""Longest the pty thread blocks, so ``stop()`` returns promptly (s)."""
JOIN_TIMEOUT_S = 2.0


class _ToHost(can.Listener):
    """Notifier listener: every frame heard on the bus goes to the host (if it may pass)."""

    def __init__(self, emulator: SlcanAdapterEmulator) -> None:
        self._emulator = emulator

    def on_message_received(self, msg: can.Message) -> None:
        """Pass one received classic CAN frame to the host."""
        if msg.is_error_frame or msg.is_fd or msg.dlc > 8:
            return
        frame = CanFrame(
            msg.arbitration_id,
            b"" if msg.is_remote_frame else bytes(msg.data),
            msg.is_extended_id,
            msg.is_remote_frame,
            msg.dlc,
        )
        self._emulator._to_host(frame)

    def on_error(self, exc: Exception) -> None:
        """Log a bus receive failure (the Notifier stops on it)."""
        log.error("slcan emulator: bus receive failed: %s", exc)


class SlcanAdapterEmulator(Emulator):
    """A LAWICEL adapter on a pty, bridging to a python-can bus.

    Args:
        bus: the CAN side (not shut down by the emulator); default: a new
            ``virtual`` bus on ``channel``, shut down on close.
        channel: virtual channel name when no bus is given.
        bus_bitrate: the bitrate of that bus (bit/s); a host choosing another
            hears nothing, as on a real bus.
        model: the adapter's rules and state (default: a new one at ``bus_bitrate``).
    """

    def __init__(
        self,
        *,
        bus: can.BusABC | None = None,
        channel: str = "forcelearn-jr3",
        bus_bitrate: int = 1_000_000,
        model: SlcanAdapterModel | None = None,
    ) -> None:
        self.model = model or SlcanAdapterModel(bus_bitrate)
        self._owns_bus = bus is None
        self.bus = bus if bus is not None else can.Bus(interface="virtual", channel=channel)
        self._port = PtyEndpoint("slcan")
        self._lines = LineSplitter()
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._notifier: can.Notifier | None = None
        self._t0 = time.monotonic()
        self.on_open: Callable[[], None] | None = None
        """Called when a host opens the channel (``O``), before the reply: a new client session."""

    @property
    def address(self) -> str:
        """The serial port to open (a symlink to the pty): python-can's slcan ``channel``."""
        return self._port.address

    def _start_serving(self) -> None:
        """Two daemon threads: the pty side and the bus side."""
        self._notifier = can.Notifier(self.bus, [_ToHost(self)], timeout=POLL_S)
        self._thread = threading.Thread(target=self._serve, name="slcan-emulator", daemon=True)
        self._thread.start()
        log.info("slcan adapter emulator serving on %s", self.address)

    def _release(self) -> None:
        """Stop both threads (joined), release the pty and the bus if made here."""
        self._stop.set()
        if self._notifier is not None:
            self._notifier.stop(timeout=JOIN_TIMEOUT_S)
        if self._thread is not None:
            self._thread.join(JOIN_TIMEOUT_S)
            if self._thread.is_alive():  # pragma: no cover - would be a bug in _serve
                log.error("slcan emulator thread did not stop within %.1f s", JOIN_TIMEOUT_S)
        self._port.close()
        if self._owns_bus:
            self.bus.shutdown()

    def _serve(self) -> None:
        while not self._stop.is_set():
            data = self._port.read(POLL_S)
            for line in self._lines.feed(data) if data else ():
                self._answer(line)

    def _answer(self, line: bytes) -> None:
        with self._lock:
            was_open = self.model.is_open
            outcome = self.model.handle(parse_line(line))
            opened = self.model.is_open and not was_open
        if opened and self.on_open is not None:
            self.on_open()
        frame = outcome.to_bus
        if frame is not None:
            msg = can.Message(arbitration_id=frame.arbitration_id, data=frame.data,
                              is_extended_id=frame.extended, is_remote_frame=frame.remote,
                              dlc=frame.dlc)
            try:
                self.bus.send(msg)
            except can.CanError as exc:
                log.warning("slcan emulator: could not send to the bus: %s", exc)
                with self._lock:
                    self.model.flags |= FLAG_BUS_ERROR
        if outcome.reply:
            self._port.write(outcome.reply)

    def _to_host(self, frame: CanFrame) -> None:
        now_ms = int((time.monotonic() - self._t0) * 1000)
        with self._lock:
            line = self.model.from_bus(frame, now_ms)
            if line and not self._port.write(line):
                self.model.overrun()
