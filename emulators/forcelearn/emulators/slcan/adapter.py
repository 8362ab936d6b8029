"""The slcan adapter's behaviour, pure: a command in, the reply and any frame for the bus out.

:class:`SlcanAdapterModel` is what a LAWICEL adapter does between its serial
line and its CAN controller, without either: the server feeds it parsed host
lines (:meth:`~SlcanAdapterModel.handle`) and frames received from the bus
(:meth:`~SlcanAdapterModel.from_bus`), and moves the bytes and frames it
returns. Rules (those of the LAWICEL adapters; leniencies marked *):

* Power-up: channel closed, bitrate 1 Mbit/s (*so a host that sends only
  ``O`` works, as with adapters that remember their last bitrate), timestamps
  off.
* ``S``/``s``/``Z`` only while closed; ``O``/``L`` only while closed;
  ``C`` always succeeds* (python-can sends ``C`` before setting the bitrate).
* Frames are sent only while open and not listen-only; received frames reach
  the host only while open.
* A bitrate other than the bus's is what a wrong bitrate is on a real bus:
  the adapter's frames are never acknowledged and it hears only errors, so
  nothing passes in either direction and the status flags report bus errors.
* ``F`` answers only while open and clears the flags it reports.
* CAN FD lines (``d``/``D``/``b``/``B``) and acceptance filters (``M``/``m``)
  are not supported and answered with BEL, as a classic-CAN adapter does.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

from forcelearn.protocols import lawicel
from forcelearn.protocols.lawicel import BEL, CR, CanFrame, Command, Invalid

log = logging.getLogger(__name__)

FLAG_RX_FIFO_FULL = 0x01
FLAG_TX_FIFO_FULL = 0x02
FLAG_ERROR_WARNING = 0x04
FLAG_DATA_OVERRUN = 0x08
FLAG_ERROR_PASSIVE = 0x20
FLAG_ARBITRATION_LOST = 0x40
FLAG_BUS_ERROR = 0x80
POWER_UP_BITRATE = 1_000_000
"""Bitrate (bit/s) the adapter uses until told otherwise."""


@dataclass(frozen=True)
class Outcome:
    """What one host command produced: bytes for the host, and a frame for the bus or None."""

    reply: bytes
    to_bus: CanFrame | None = None


class SlcanAdapterModel:
    """State and rules of one emulated LAWICEL adapter.

    Args:
        bus_bitrate: the bitrate of the bus the adapter is plugged into (bit/s).
        hardware_version, software_version: what ``V`` reports (0..99 each).
        serial_number: what ``N`` reports (4 ASCII letters or digits).
    """

    def __init__(
        self,
        bus_bitrate: int = POWER_UP_BITRATE,
        *,
        hardware_version: int = 10,
        software_version: int = 13,
        serial_number: str = "FL01",
    ) -> None:
        self.bus_bitrate = bus_bitrate
        self._version = lawicel.version_reply(hardware_version, software_version)
        self._serial = lawicel.serial_reply(serial_number)
        self.is_open = False
        self.listen_only = False
        self.bitrate: int | None = POWER_UP_BITRATE
        """Bitrate set by ``S<n>`` (bit/s); None after ``s`` (custom BTR registers)."""
        self.timestamps = False
        self.flags = 0
        self.frames_sent = 0
        self.frames_received = 0
        self.errors = 0

    @property
    def on_bus(self) -> bool:
        """True when frames pass: open, at the bus's bitrate."""
        return self.is_open and self.bitrate == self.bus_bitrate

    def handle(self, command: Command | Invalid) -> Outcome:
        """Apply one host command; return the reply and any frame to put on the bus."""
        outcome = self._apply(command)
        if outcome.reply.endswith(BEL):
            self.errors += 1
            log.info("slcan: refused %r", command)
        return outcome

    def _apply(self, command: Command | Invalid) -> Outcome:
        closed_only = (lawicel.SetBitrate, lawicel.SetBtr, lawicel.Timestamps, lawicel.Open)
        if isinstance(command, closed_only) and self.is_open:
            return Outcome(BEL)
        match command:
            case lawicel.Empty():
                return Outcome(b"")
            case lawicel.Open(listen_only=listen_only):
                self.is_open, self.listen_only, self.flags = True, listen_only, 0
            case lawicel.Close():
                self.is_open = False
            case lawicel.SetBitrate(bitrate=bitrate):
                self.bitrate = bitrate
            case lawicel.SetBtr():
                self.bitrate = None
            case lawicel.Timestamps(on=on):
                self.timestamps = on
            case lawicel.Version():
                return Outcome(self._version)
            case lawicel.SerialNumber():
                return Outcome(self._serial)
            case lawicel.StatusFlags() if self.is_open:
                flags, self.flags = self.flags, 0
                return Outcome(lawicel.status_reply(flags))
            case lawicel.Transmit(frame=frame) if self.is_open and not self.listen_only:
                return self._transmit(frame)
            case _:
                return Outcome(BEL)
        return Outcome(CR)

    def _transmit(self, frame: CanFrame) -> Outcome:
        reply = lawicel.transmit_reply(frame)
        if not self.on_bus:  # nobody acknowledges: the controller counts errors
            self.flags |= FLAG_BUS_ERROR | FLAG_ERROR_PASSIVE
            return Outcome(reply)
        self.frames_sent += 1
        return Outcome(reply, frame)

    def from_bus(self, frame: CanFrame, now_ms: int) -> bytes:
        """Return the line for the host for a frame heard on the bus (b"" if it cannot pass)."""
        if not self.is_open:
            return b""
        if not self.on_bus:
            self.flags |= FLAG_BUS_ERROR
            return b""
        self.frames_received += 1
        return lawicel.encode_frame(frame, now_ms if self.timestamps else None)

    def overrun(self) -> None:
        """Note that a line for the host was lost (the serial side was full)."""
        self.flags |= FLAG_DATA_OVERRUN | FLAG_RX_FIFO_FULL
