"""The link layer against a scripted in-process port: no sockets, no timing.

The fake controller answers synchronously inside ``write``, so every test
counts bytes and frames instead of waiting.
"""

from __future__ import annotations

import pytest

from forcelearn.drivers.computer_link import LinkConfig
from forcelearn.drivers.computer_link.link import Link
from forcelearn.errors import LinkError, LinkTimeout
from forcelearn.protocols.computer_link import framing
from forcelearn.protocols.computer_link import messages as m

ACK, NAK = framing.Control.ACK, framing.Control.NAK
UNDECODABLE = framing.encode(b"\x03\x00")  # passes the CRC, shorter than a reply header


class ScriptedController:
    """A pyserial-like port whose far end executes requests and may send bad replies.

    ``bad_replies`` undecodable frames are sent before the real reply; a NAK
    from the PC asks for the reply again (never a second execution).
    ``silent_until_enq``: the controller executes a request at once but sends
    nothing until that many DLE ENQs have arrived (an ACK "delayed past the
    timeout", decided by counting, not by the clock).
    """

    def __init__(self, bad_replies: int = 0, silent_until_enq: int = 0) -> None:
        self.bad_left = bad_replies
        self.silent_until_enq = silent_until_enq
        self.enqs = 0
        self.executed: list[int] = []
        self.received: list[framing.Frame] = []
        self._reader = framing.FrameReader()
        self._out = bytearray()
        self._last_reply = b""
        self._last_tns: int | None = None

    @property
    def in_waiting(self) -> int:
        """Bytes ready to read."""
        return len(self._out)

    def reset_input_buffer(self) -> None:
        """Drop unread bytes."""
        self._out.clear()

    def read(self, size: int) -> bytes:
        """Return up to ``size`` ready bytes (never blocks)."""
        data = bytes(self._out[:size])
        del self._out[:size]
        return data

    def write(self, data: bytes) -> int:
        """Take the PC's bytes and queue the controller's answers at once."""
        for frame in self._reader.feed(data):
            self.received.append(frame)
            if isinstance(frame, framing.DataFrame):
                request = m.decode_request(frame.payload)
                if request.transaction != self._last_tns:
                    self._last_tns = request.transaction
                    self.executed.append(request.transaction)
                    reply = m.Reply(request.command, request.transaction, m.ErrorCode.OK)
                    self._last_reply = framing.encode(m.encode_reply(reply))
                if self.enqs >= self.silent_until_enq:
                    self._out += ACK.wire + self._next_reply()
            elif frame is framing.Control.ENQ:
                self.enqs += 1
                if self.enqs >= self.silent_until_enq:
                    self._out += self._next_reply()
            elif frame is NAK:
                self._out += self._next_reply()
        return len(data)

    def _next_reply(self) -> bytes:
        if self.bad_left > 0:
            self.bad_left -= 1
            return UNDECODABLE
        return self._last_reply


def _link(port: ScriptedController, nak_retries: int = 3) -> Link:
    return Link(port, LinkConfig(url="loop://", nak_retries=nak_retries))  # type: ignore[arg-type]


def test_undecodable_reply_is_nakked_and_the_reply_fetched_again() -> None:
    """A CRC-valid frame that is not a reply is damaged: NAK, retry, counted."""
    port = ScriptedController(bad_replies=1)
    link = _link(port)
    reply = link.transact(m.Command.MOVE_BY, m.increment_body((0.0, 0.0, -1.0)))
    assert reply.command is m.Command.MOVE_BY
    assert len(port.executed) == 1, "the move ran more than once"
    assert port.received.count(NAK) == 1
    assert port.received.count(ACK) == 1  # only the good reply is acknowledged
    assert link.damaged_frames == 1


def test_undecodable_replies_past_the_retries_end_in_link_error() -> None:
    """Replies that never decode end the transaction with LinkError, the move run once."""
    port = ScriptedController(bad_replies=100)
    link = _link(port, nak_retries=2)
    with pytest.raises(LinkError, match="damaged 3 times"):
        link.transact(m.Command.MOVE_BY, m.increment_body((0.0, 0.0, -1.0)))
    assert len(port.executed) == 1
    assert port.received.count(NAK) == 2
    assert link.damaged_frames == 3


def test_a_controller_silent_past_the_timeout_is_asked_again_and_moves_once() -> None:
    """No ACK until the 2nd ENQ: the repeated reply ends the call, the move ran once."""
    port = ScriptedController(silent_until_enq=2)
    link = _link(port)
    reply = link.transact(m.Command.MOVE_BY, m.increment_body((3.0, 0.0, 0.0)))
    assert reply.command is m.Command.MOVE_BY and reply.error == m.ErrorCode.OK
    assert port.enqs == 2
    assert len(port.executed) == 1
    assert sum(isinstance(f, framing.DataFrame) for f in port.received) == 1  # no retransmit


def test_a_controller_silent_past_every_enq_gives_link_timeout() -> None:
    """Silent through all ENQs: LinkTimeout after exactly enq_retries ENQs; never doubled."""
    port = ScriptedController(silent_until_enq=100)
    link = Link(port, LinkConfig(url="loop://", ack_timeout_s=0.01, enq_retries=3))  # type: ignore[arg-type]
    with pytest.raises(LinkTimeout, match="may have executed"):
        link.transact(m.Command.MOVE_BY, m.increment_body((3.0, 0.0, 0.0)))
    assert port.enqs == 3
    assert len(port.executed) == 1
