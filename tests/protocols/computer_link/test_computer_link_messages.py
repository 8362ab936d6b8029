"""Application messages of the computer link: layouts, round trips, malformed payloads."""

from __future__ import annotations

import pytest
from hypothesis import given
from hypothesis import strategies as st

from forcelearn.errors import ProtocolError
from forcelearn.protocols.computer_link import messages as m


def test_move_to_request_has_the_documented_layout() -> None:
    """Code, little-endian transaction number, then seven float32 values."""
    body = m.pose_body((1.0, 2.0, 3.0), (1.0, 0.0, 0.0, 0.0))
    payload = m.encode_request(m.Command.MOVE_TO, 0x1234, body)
    assert payload[:3] == bytes((0x03, 0x34, 0x12))
    assert len(payload) == 3 + 7 * 4
    assert payload[3:7] == bytes.fromhex("0000803f")  # 1.0f little-endian


@given(
    st.sampled_from(list(m.Command)),
    st.integers(0, 0xFFFF),
)
def test_request_round_trip(command: m.Command, transaction: int) -> None:
    """Any command with a body of its size decodes back to the same request."""
    size = {m.Command.MOVE_TO: 28, m.Command.MOVE_BY: 12, m.Command.SET_SPEED: 4}.get(command, 0)
    body = bytes(range(size))
    request = m.decode_request(m.encode_request(command, transaction, body))
    assert request == m.Request(command, transaction, body)


def test_reply_round_trip_ok_and_error() -> None:
    """An OK reply carries its body; an error reply its code and reason."""
    ok = m.Reply(m.Command.READ_STATUS, 7, m.ErrorCode.OK, body=b"\x01\x00\x05\x00\x00\x00")
    assert m.decode_reply(m.encode_reply(ok)) == ok
    bad = m.Reply(m.Command.MOVE_TO, 8, m.ErrorCode.OUT_OF_WORKSPACE, reason="z below floor")
    payload = m.encode_reply(bad)
    assert payload[:4] == bytes((0x83, 8, 0, 3))
    assert m.decode_reply(payload) == bad


@given(
    st.tuples(*[st.floats(-2000, 2000, width=32)] * 3),
    st.tuples(*[st.floats(-1, 1, width=32)] * 4),
    st.tuples(*[st.floats(-360, 360, width=32)] * 6),
)
def test_position_round_trip_is_exact_for_float32_values(xyz, quat, joints) -> None:
    """Values representable in float32 travel unchanged."""
    position = m.Position(xyz, quat, joints)
    assert m.parse_position(m.position_body(position)) == position


def test_status_identify_speed_increment_round_trips() -> None:
    """The small bodies decode to what was encoded."""
    status = m.Status(moving=True, in_position=False, last_error=3, move_count=70_000)
    assert m.parse_status(m.status_body(status)) == status
    assert m.parse_identify(m.identify_body((1, 0), "S3 emulator")) == ((1, 0), "S3 emulator")
    assert m.parse_speed(m.speed_body(12.5)) == 12.5
    assert m.parse_increment(m.increment_body((0.5, -0.25, 1.0))) == (0.5, -0.25, 1.0)


@pytest.mark.parametrize(
    ("payload", "match"),
    [
        (b"\x03", "shorter"),
        (b"\x7f\x00\x00", "unknown command"),
        (b"\x03\x00\x00\x01\x02", "MOVE_TO body"),
        (b"\x06\x00\x00\xff", "STOP body"),
    ],
)
def test_malformed_requests_raise_protocol_error(payload: bytes, match: str) -> None:
    """A malformed request is a ProtocolError naming the fault."""
    with pytest.raises(ProtocolError, match=match):
        m.decode_request(payload)


@pytest.mark.parametrize(
    ("payload", "match"),
    [
        (b"\x83\x00", "shorter"),
        (b"\x03\x00\x00\x00", "not a reply"),
        (b"\xff\x00\x00\x00", "unknown"),
    ],
)
def test_malformed_replies_raise_protocol_error(payload: bytes, match: str) -> None:
    """A malformed reply is a ProtocolError naming the fault."""
    with pytest.raises(ProtocolError, match=match):
        m.decode_reply(payload)


def test_wrong_body_size_is_refused_on_both_sides() -> None:
    """Encoding a wrong-size body is a ValueError; parsing one a ProtocolError."""
    with pytest.raises(ValueError, match="body"):
        m.encode_request(m.Command.SET_SPEED, 1, b"\x00")
    with pytest.raises(ProtocolError, match="expected 52"):
        m.parse_position(b"\x00" * 51)
