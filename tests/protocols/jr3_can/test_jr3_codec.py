"""Codec: golden frames, round trips for every opcode, and fuzzing that never raises."""

from __future__ import annotations

import dataclasses

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from forcelearn.protocols.jr3_can import codec
from forcelearn.protocols.jr3_can.codec import (
    Ack,
    Bootup,
    Decoded,
    Forces,
    GetForceFullScales,
    GetMomentFullScales,
    GetState,
    Moments,
    Rejected,
    RejectReason,
    Reset,
    SetFilter,
    StartAsync,
    StartSync,
    Stop,
    Sync,
    ZeroOffsets,
    decode,
    encode,
)
from forcelearn.protocols.jr3_can.opcodes import JR3_MBED_2023_12, OpcodeMap

ONE_OF_EACH = [
    Sync(),
    Ack(0),
    Ack(1),
    Ack(0, (100, 200, 65535)),
    StartSync(50000),
    StartAsync(200, 10000),
    Stop(),
    ZeroOffsets(),
    SetFilter(12500),
    GetState(),
    GetForceFullScales(),
    GetMomentFullScales(),
    Reset(),
    Forces((-32768, 0, 32767), 65535),
    Moments((1, -1, 1234), 0),
    Bootup(),
]


def test_every_opcode_of_the_map_has_a_message_under_test() -> None:
    """The round-trip list covers every kind in the opcode table."""
    assert {m.kind for m in ONE_OF_EACH} == set(JR3_MBED_2023_12.by_kind())


@pytest.mark.parametrize("node_id", [1, 5, 127])
@pytest.mark.parametrize("message", ONE_OF_EACH, ids=lambda m: repr(m))
def test_round_trip(message: codec.Message, node_id: int) -> None:
    """Encoding then decoding gives back the same message and node id."""
    frame = encode(message, node_id)
    result = decode(frame.arbitration_id, frame.data)
    assert result == Decoded(0 if isinstance(message, Sync) else node_id, message)


def test_golden_async_start_from_the_adapter_documentation() -> None:
    """Start async, 2 Hz cut-off, 10 ms period, node 1 is id 0x201, data C8 00 10 27 00 00."""
    frame = encode(StartAsync(cutoff_centi_hz=200, period_us=10_000), node_id=1)
    assert frame == (0x201, bytes.fromhex("C8 00 10 27 00 00"))


def test_golden_force_frame_is_little_endian() -> None:
    """Forces (-2, 1, 0x1234) counter 0x0102 on node 3 lay out as int16 LE + uint16 LE."""
    frame = encode(Forces((-2, 1, 0x1234), 0x0102), node_id=3)
    assert frame == (0x603, bytes.fromhex("FEFF 0100 3412 0201"))


def test_sync_is_the_bare_opcode_whatever_the_node() -> None:
    """SYNC goes to all nodes on id 0x080 with no payload."""
    assert encode(Sync(), node_id=9) == (0x080, b"")


@pytest.mark.parametrize(
    ("arbitration_id", "data", "reason"),
    [
        (0x601, b"\x00" * 7, RejectReason.BAD_LENGTH),
        (0x101, b"\x00" * 3, RejectReason.BAD_LENGTH),
        (0x281, b"\x00", RejectReason.BAD_LENGTH),
        (0x081, b"", RejectReason.BAD_NODE_ID),
        (0x600, b"\x00" * 8, RejectReason.BAD_NODE_ID),
        (0x001, b"", RejectReason.UNKNOWN_OPCODE),
        (0x781, b"", RejectReason.UNKNOWN_OPCODE),
        (0x800, b"", RejectReason.ID_OUT_OF_RANGE),
    ],
)
def test_malformed_frames_are_rejected_with_a_reason(
    arbitration_id: int, data: bytes, reason: RejectReason
) -> None:
    """Wrong lengths, node ids and opcodes come back as a typed Rejected result."""
    assert decode(arbitration_id, data) == Rejected(reason, arbitration_id, data)


def test_extended_ids_are_rejected() -> None:
    """A 29-bit frame is never taken for an adapter frame, even with a matching low part."""
    assert decode(0x601, b"\x00" * 8, is_extended_id=True).reason is RejectReason.EXTENDED_ID


@pytest.mark.parametrize(
    "message",
    [StartSync(70000), StartAsync(1, 1 << 32), Forces((40000, 0, 0), 1), Moments((0, 0, 0), -1),
     Ack(0, (1, 2, 70000)), Ack(300)],
)
def test_encode_refuses_values_outside_their_wire_range(message: codec.Message) -> None:
    """A value that cannot be sent raises ValueError instead of wrapping silently."""
    with pytest.raises(ValueError):
        encode(message, node_id=1)


@pytest.mark.parametrize("node_id", [0, 128, -1])
def test_encode_refuses_bad_node_ids(node_id: int) -> None:
    """Node ids are 1..127."""
    with pytest.raises(ValueError, match="node_id"):
        encode(Stop(), node_id)


def test_another_opcode_map_changes_the_ids() -> None:
    """The codec uses the map it is given, never a literal opcode."""
    shifted = dataclasses.replace(JR3_MBED_2023_12, version="test", stop=0x780)
    frame = encode(Stop(), 1, shifted)
    assert frame.arbitration_id == 0x781
    assert decode(0x781, b"", opcodes=shifted) == Decoded(1, Stop())
    assert isinstance(decode(0x281, b"", opcodes=shifted), Rejected)


def test_opcode_map_validation() -> None:
    """An opcode with node bits set or two kinds on one opcode is refused."""
    with pytest.raises(ValueError):
        dataclasses.replace(JR3_MBED_2023_12, stop=0x281)
    with pytest.raises(ValueError):
        dataclasses.replace(JR3_MBED_2023_12, stop=JR3_MBED_2023_12.reset)
    assert isinstance(JR3_MBED_2023_12, OpcodeMap)


@settings(max_examples=1500, deadline=None)
@given(
    arbitration_id=st.one_of(st.integers(0, 0x7FF), st.integers(-5, 1 << 30)),
    data=st.binary(max_size=64),
    extended=st.booleans(),
)
def test_decoder_never_raises_and_accepted_frames_re_encode_identically(
    arbitration_id: int, data: bytes, extended: bool
) -> None:
    """Any id, length and payload decodes to Decoded or Rejected; Decoded re-encodes exactly."""
    result = decode(arbitration_id, data, is_extended_id=extended)
    assert isinstance(result, Decoded | Rejected)
    if isinstance(result, Decoded):
        assert encode(result.message, result.node_id or 1) == (arbitration_id, data)
