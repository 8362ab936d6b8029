"""The LAWICEL line codec: golden lines, round trips, splitting, and a fuzz of the parser."""

from __future__ import annotations

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from forcelearn.protocols import lawicel
from forcelearn.protocols.lawicel import (
    MAX_LINE,
    CanFrame,
    Invalid,
    LineSplitter,
    Transmit,
    encode_command,
    encode_frame,
    parse_frame,
    parse_line,
)

GOLDEN: list[tuple[bytes, object]] = [
    (b"t1232ABCD", Transmit(CanFrame(0x123, b"\xab\xcd"))),
    (b"t0800", Transmit(CanFrame(0x080))),
    (b"T1FFFFFFF80102030405060708",
     Transmit(CanFrame(0x1FFFFFFF, bytes(range(1, 9)), extended=True))),
    (b"r7FF8", Transmit(CanFrame(0x7FF, remote=True, dlc=8))),
    (b"R000001003", Transmit(CanFrame(0x100, extended=True, remote=True, dlc=3))),
    (b"S8", lawicel.SetBitrate(1_000_000)),
    (b"S0", lawicel.SetBitrate(10_000)),
    (b"S9", lawicel.SetBitrate(83_300)),
    (b"s031C", lawicel.SetBtr(0x03, 0x1C)),
    (b"O", lawicel.Open()),
    (b"L", lawicel.Open(listen_only=True)),
    (b"C", lawicel.Close()),
    (b"V", lawicel.Version()),
    (b"N", lawicel.SerialNumber()),
    (b"F", lawicel.StatusFlags()),
    (b"Z0", lawicel.Timestamps(on=False)),
    (b"Z1", lawicel.Timestamps(on=True)),
    (b"", lawicel.Empty()),
]


@pytest.mark.parametrize(("line", "command"), GOLDEN)
def test_golden_lines_parse_and_encode_back(line: bytes, command: object) -> None:
    """Each documented line parses to its command, and the command encodes to the line."""
    assert parse_line(line) == command
    assert encode_command(command) == line + b"\r"  # type: ignore[arg-type]


@pytest.mark.parametrize(
    "line",
    [
        b"t12", b"t1239", b"t1231A", b"t1232ABCDEF", b"t12320G00", b"tXYZ0",
        b"T2000000000",  # 29-bit identifier above 0x1FFFFFFF
        b"t8000",  # 11-bit identifier above 0x7FF
        b"r1231AB", b"S", b"SA", b"S10", b"s03", b"s0G1C", b"X", b"O1", b"Z2",
        b"d1231AB", b"D000001231AB", b"Y2", b"M00000000",  # CAN FD, acceptance filter
        b"t1232ABCD0000",  # a host line never carries a timestamp
        b"t" + b"0" * MAX_LINE,
    ],
)
def test_malformed_or_unsupported_lines_are_invalid(line: bytes) -> None:
    """Wrong lengths, non-hex digits, ids out of range, FD and filters: Invalid, never raise."""
    result = parse_line(line)
    assert isinstance(result, Invalid), result
    assert result.reason


def test_frames_from_the_adapter_may_carry_a_timestamp() -> None:
    """With timestamps on, 4 hex digits of ms (wrapping at 60000) follow the data."""
    frame = CanFrame(0x601, bytes(8))
    line = encode_frame(frame, timestamp_ms=60_001)
    assert line == b"t6018" + b"00" * 8 + b"0001\r"
    assert parse_frame(line[:-1], allow_timestamp=True) == frame


def test_replies_have_the_forms_python_can_reads() -> None:
    """V: two 2-digit decimals; N: 4 characters; F: 2 hex digits; z/Z after a transmit."""
    assert lawicel.version_reply(10, 13) == b"V1013\r"
    assert lawicel.serial_reply("FL01") == b"NFL01\r"
    assert lawicel.status_reply(0xA0) == b"FA0\r"
    assert lawicel.transmit_reply(CanFrame(1)) == b"z\r"
    assert lawicel.transmit_reply(CanFrame(1, extended=True)) == b"Z\r"
    with pytest.raises(ValueError):
        lawicel.serial_reply("TOO-LONG")


frames = st.builds(
    lambda extended, remote, ident, data, dlc: CanFrame(
        ident if extended else ident & 0x7FF,
        b"" if remote else data,
        extended,
        remote,
        dlc if remote else None,
    ),
    st.booleans(),
    st.booleans(),
    st.integers(0, 0x1FFFFFFF),
    st.binary(max_size=8),
    st.integers(0, 8),
)


@given(frame=frames, split=st.integers(0, 30))
def test_any_frame_round_trips_in_any_pieces(frame: CanFrame, split: int) -> None:
    """Encode -> split -> parse gives the frame back however the bytes arrive."""
    wire = encode_command(Transmit(frame))
    feeds = [[wire], [wire[:split], wire[split:]], [wire[i : i + 1] for i in range(len(wire))]]
    for pieces in feeds:
        splitter = LineSplitter()
        lines = [line for piece in pieces for line in splitter.feed(piece)]
        assert [parse_line(line) for line in lines] == [Transmit(frame)]


def test_splitter_resynchronises_after_garbage_and_drops_line_feeds() -> None:
    """An over-long run of garbage costs one Invalid line; CR LF ends lines like CR."""
    splitter = LineSplitter()
    lines = splitter.feed(b"x" * 500 + b"\rO\r\nt0800\r\nV")
    assert len(lines[0]) == MAX_LINE + 1 and isinstance(parse_line(lines[0]), Invalid)
    assert [parse_line(line) for line in lines[1:]] == [
        lawicel.Open(), Transmit(CanFrame(0x080))
    ]
    assert splitter.feed(b"\r") == [b"V"]


@settings(max_examples=300)
@given(chunks=st.lists(st.binary(max_size=80), max_size=12))
def test_fuzz_parser_never_raises_and_valid_commands_re_encode(chunks: list[bytes]) -> None:
    """Arbitrary bytes: bounded lines, parse_line never raises, valid results re-encode."""
    splitter = LineSplitter()
    for chunk in chunks:
        for line in splitter.feed(chunk):
            assert len(line) <= MAX_LINE + 1
            result = parse_line(line)
            if not isinstance(result, Invalid):
                assert parse_line(encode_command(result)[:-1]) == result


@given(
    ident=st.integers(0, 0x7FF),
    data=st.binary(max_size=8),
    noise=st.binary(max_size=40).filter(lambda b: b"\r" not in b),
)
def test_fuzz_a_valid_line_after_noise_is_still_read(ident: int, data: bytes, noise: bytes) -> None:
    """Noise up to a CR never hides the next valid line."""
    frame = CanFrame(ident, data)
    lines = LineSplitter().feed(noise + b"\r" + encode_frame(frame))
    assert parse_line(lines[-1]) == Transmit(frame)
