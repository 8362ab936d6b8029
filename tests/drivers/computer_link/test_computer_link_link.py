"""The link layer against a scripted in-process port: no sockets, no timing.

The fake controller answers synchronously inside ``write``, so every test
counts bytes and frames instead of waiting.
"""

from __future__ import annotations

import pytest

from forcelearn.drivers.computer_link import LinkConfig, framing
from forcelearn.drivers.computer_link import messages as m
from forcelearn.drivers.computer_link.link import Link
from forcelearn.errors import LinkError

ACK, NAK = framing.Control.ACK, framing.Control.NAK
UNDECODABLE = framing.encode(b"\x03\x00")  # passes the CRC, shorter than a reply header


class ScriptedController:
    """A pyserial-like port whose far end executes requests and may send bad replies.

    ``bad_replies`` undecodable frames are sent before the real reply; a NAK
    from the PC asks for the reply again (never a second execution).
    """

    def __init__(self, bad_replies: int) -> None:
        self.bad_left = bad_replies
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
                self._out += ACK.wire + self._next_reply()
            elif frame in (NAK, framing.Control.ENQ):
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
    """Issue 12.1: a CRC-valid frame that is not a reply is damaged: NAK, retry, counted."""
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
