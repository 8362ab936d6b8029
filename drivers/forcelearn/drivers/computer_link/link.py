"""One request/reply transaction of the computer link, with the documented retries.

The PC is the master: it sends one request and waits for its reply before the
next. For each transaction (docs/computer-link.md, "Retries"):

1. Unread input is discarded (the previous transaction is over), then the
   request frame is sent with a new transaction number.
2. DLE ACK: wait ``reply_timeout_s`` for the reply. DLE NAK: retransmit the
   same frame. A reply frame is taken as its own acknowledgement.
3. Nothing within the timeout: send DLE ENQ (the controller repeats its last
   reply, or DLE NAK if it has none). A repeated reply to an *earlier*
   request proves this one was lost: retransmit it.
4. A damaged reply: answer DLE NAK; the controller sends it again. A frame
   whose check passes but whose payload is not a well-formed reply is
   damaged too (NAKed, never ACKed, and counted in ``damaged_frames``).
5. Every intact frame from the controller is answered with DLE ACK; replies
   with another transaction number are stale and ignored.

Retransmissions and NAKs sent are each capped at ``nak_retries``, ENQs at
``enq_retries``; then :class:`LinkError` / :class:`LinkTimeout`. A
retransmitted request keeps its transaction number, so the controller never
executes it twice.
"""

from __future__ import annotations

import collections
import logging
import secrets
import threading
import time
from collections.abc import Callable
from typing import Protocol, TypeVar

import serial

from forcelearn.drivers.computer_link.config import LinkConfig
from forcelearn.errors import LinkError, LinkTimeout, ProtocolError, RobotFault
from forcelearn.protocols.computer_link import framing
from forcelearn.protocols.computer_link import messages as m

log = logging.getLogger(__name__)

try:  # pyserial on POSIX lets termios.error (not an OSError) out of a hung-up pty
    import termios

    PORT_ERRORS: tuple[type[BaseException], ...] = (serial.SerialException, OSError, termios.error)
except ImportError:  # pragma: no cover - Windows
    PORT_ERRORS = (serial.SerialException, OSError)

_T = TypeVar("_T")

_ACK = framing.Control.ACK.wire
_NAK = framing.Control.NAK.wire
_ENQ = framing.Control.ENQ.wire


class SerialPort(Protocol):
    """What the link uses of an open pyserial port (``serial.Serial``, a URL handler's port)."""

    @property
    def in_waiting(self) -> int:
        """Bytes received and not yet read."""
        ...

    def read(self, size: int = 1, /) -> bytes:
        """Up to ``size`` bytes (fewer at the port's timeout)."""
        ...

    def write(self, data: bytes, /) -> int | None:
        """Send ``data``."""
        ...

    def reset_input_buffer(self) -> None:
        """Drop what was received and not yet read."""
        ...


class Link:
    """Transactions over an open pyserial port; thread-safe (one at a time).

    After the port fails, every call raises :class:`LinkError` until the owner
    replaces the link: a lost link is reported, never silently reopened.
    """

    def __init__(self, port: SerialPort, config: LinkConfig) -> None:
        self._port = port
        self._carry: Callable[[bytes], bytes | None] | None = getattr(port, "carry_payload", None)
        """The port's in-process short cut (``EmulatedRobotSerial.carry_payload``), if any."""
        self._carry_status: Callable[[bytes], m.Status | None] | None = getattr(
            port, "carry_status", None)
        """The port's in-process short cut for READ_STATUS (``EmulatedRobotSerial.carry_status``):
        the status the reply would carry, the payloads neither encoded nor decoded."""
        self._config = config
        self._reader = framing.FrameReader()
        self._pending: collections.deque[framing.Frame] = collections.deque()
        self._lock = threading.Lock()
        self._transaction = secrets.randbelow(0x10000)
        self._broken: str | None = None
        self.damaged_frames = 0
        """Frames from the controller NAKed as damaged (check failed or undecodable)."""

    def transact(self, command: m.Command, body: bytes = b"") -> m.Reply:
        """Send one request, return its OK reply; RobotFault if the controller refused it."""
        with self._lock:
            reply = self._guarded(self._transact, command, body)
        if reply.error != m.ErrorCode.OK:
            raise RobotFault(reply.error, reply.reason)
        return reply

    def read_status(self) -> m.Status:
        """``parse_status(transact(READ_STATUS).body)``; in process, the status carried as it is.

        With a port that carries statuses (``carry_status``) the same transaction
        (number, clock, wires) without the request and reply payloads parsed or the
        reply built as a message; otherwise, or when that port says the frames must
        go, :meth:`transact`.
        """
        if self._carry_status is not None:
            with self._lock:
                answer = self._guarded(self._poll_status)
            if isinstance(answer, m.Status):
                return answer  # what the carried reply's body parses to
        else:
            answer = self.transact(m.Command.READ_STATUS)
        if answer.error != m.ErrorCode.OK:
            raise RobotFault(answer.error, answer.reason)
        return m.parse_status(answer.body)

    def _guarded(self, transact: Callable[..., _T], *args: object) -> _T:
        """``transact(*args)`` on a link that is up; a port failure breaks the link (LinkError)."""
        if self._broken:
            raise self._down()
        try:
            return transact(*args)
        except LinkError:  # LinkTimeout is also an OSError (TimeoutError): keep it as is
            raise
        except PORT_ERRORS as exc:  # pyserial leaks raw OSError and termios.error
            raise self._lost(exc) from exc

    def _down(self) -> LinkError:
        """The error of a call on a broken link."""
        return LinkError(f"link is down ({self._broken}); reconnect before commanding")

    def _lost(self, exc: BaseException) -> LinkError:
        """Mark the link broken by the port failure ``exc``; the error to raise."""
        self._broken = str(exc)
        return LinkError(
            f"link to {self._config.url} lost ({exc}); the last command may or may "
            "not have executed: reconnect, then read the position"
        )

    def _transact(self, command: m.Command, body: bytes) -> m.Reply:
        """One transaction: a new number, the input discarded, the request carried or framed."""
        tns, payload = self._new_request(command, body)
        return self._exchange(command, tns, payload)

    def _poll_status(self) -> m.Reply | m.Status:
        """:meth:`_transact` of READ_STATUS, its status carried as it is if the port can."""
        tns, payload = self._new_request(m.Command.READ_STATUS, b"")
        assert self._carry_status is not None
        carried = self._carry_status(payload)
        if carried is not None:
            return carried
        return self._exchange(m.Command.READ_STATUS, tns, payload)

    def _new_request(self, command: m.Command, body: bytes) -> tuple[int, bytes]:
        """The next transaction number and its request payload; pending input discarded."""
        self._transaction = (self._transaction + 1) & 0xFFFF
        tns = self._transaction
        payload = m.encode_request(command, tns, body)
        self._port.reset_input_buffer()
        self._reader.clear()
        self._pending.clear()
        return tns, payload

    def _exchange(self, command: m.Command, tns: int, payload: bytes) -> m.Reply:
        """:meth:`_transact` once the request is made, the input discarded: carried or framed."""
        cfg = self._config
        if self._carry is not None and (answer := self._carry(payload)) is not None:
            # an in-process controller answered the payload itself: what the reply
            # frame would carry, the frames' ACKs taken as sent and received
            carried = m.decode_reply(answer)
            if carried.transaction != tns or carried.command != command:  # pragma: no cover
                raise LinkError(f"carried reply {carried} does not answer {command.name} ({tns})")
            return carried
        wire = framing.encode(payload)
        self._port.write(wire)
        retransmits = naks_sent = enqs = 0
        acked = enq_sent = False
        deadline = time.monotonic() + cfg.ack_timeout_s
        while True:
            frame = self._next_frame(deadline)
            resend = fresh_ack = False
            reply = None
            if isinstance(frame, framing.DataFrame) and (reply := _reply_or_none(frame)) is None:
                frame = framing.BadFrame("payload is not a well-formed reply")
            if frame is None:
                if enqs >= cfg.enq_retries:
                    raise LinkTimeout(
                        f"no {'reply' if acked else 'ACK'} to {command.name} (transaction "
                        f"{tns}) after {enqs} ENQ: check the cable, baud rate and that the "
                        "controller is in computer-link mode; the command may have executed"
                    )
                enqs += 1
                enq_sent = True
                self._port.write(_ENQ)
            elif frame is framing.Control.ACK:
                fresh_ack = not acked
                acked = True
            elif frame is framing.Control.NAK:
                resend = True
            elif isinstance(frame, framing.BadFrame):
                self.damaged_frames += 1
                if naks_sent >= cfg.nak_retries:
                    raise LinkError(
                        f"reply to {command.name} damaged {naks_sent + 1} times ({frame.reason}): "
                        "check for line noise and matching serial settings"
                    )
                naks_sent += 1
                self._port.write(_NAK)
            elif reply is not None:
                self._port.write(_ACK)
                if reply.transaction == tns and reply.command == command:
                    return reply
                log.debug("stale reply to transaction %d ignored", reply.transaction)
                resend = enq_sent  # the controller's last reply predates our request
            else:
                log.debug("unexpected %s from the controller ignored", frame)
            if resend:
                if retransmits >= cfg.nak_retries:
                    raise LinkError(
                        f"{command.name} rejected or lost {retransmits + 1} times: check for "
                        "line noise and matching serial settings"
                    )
                retransmits += 1
                acked = enq_sent = False
                self._port.write(wire)
            # A new wait starts after anything we sent and after the first DLE ACK of a
            # transmission; repeated ACKs, stale or unexpected frames leave it running.
            if frame is None or resend or fresh_ack or isinstance(frame, framing.BadFrame):
                timeout = cfg.reply_timeout_s if acked else cfg.ack_timeout_s
                deadline = time.monotonic() + timeout

    def _next_frame(self, deadline: float) -> framing.Frame | None:
        """Return the next received frame, or None at the deadline."""
        while not self._pending:
            if time.monotonic() >= deadline:
                return None
            data = self._port.read(max(1, self._port.in_waiting))
            if data:
                self._pending.extend(self._reader.feed(data))
        return self._pending.popleft()

    def probe_protocol(self) -> tuple[tuple[int, int], str]:
        """IDENTIFY the controller; ProtocolError if it speaks another major version."""
        version, model = m.parse_identify(self.transact(m.Command.IDENTIFY).body)
        if version[0] != m.PROTOCOL_VERSION[0]:
            raise ProtocolError(
                f"controller speaks link protocol {version[0]}.{version[1]}, this driver "
                f"{m.PROTOCOL_VERSION[0]}.{m.PROTOCOL_VERSION[1]}: update the driver or the "
                "framing/message modules"
            )
        return version, model


def _reply_or_none(frame: framing.DataFrame) -> m.Reply | None:
    """Decode a reply; None when the payload is not one (the frame is then damaged)."""
    try:
        return m.decode_reply(frame.payload)
    except ProtocolError as exc:
        log.debug("undecodable frame treated as damaged: %s", exc)
        return None
