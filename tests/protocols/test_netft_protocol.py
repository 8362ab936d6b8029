"""Golden bytes of the Net F/T wire formats, and decoders that never raise on garbage."""

from __future__ import annotations

from hypothesis import given
from hypothesis import strategies as st

from forcelearn.protocols import netft as protocol
from forcelearn.protocols.netft import CalInfo, Command, Record, Rejected, Request


def test_requests_golden_bytes() -> None:
    """Header 0x1234, command, u32 count, big-endian (the count's four bytes all count)."""
    encode = protocol.encode_request
    assert encode(Request(Command.START_REALTIME, 10)).hex() == "123400020000000a"
    assert encode(Request(Command.START_REALTIME, 0)).hex() == "1234000200000000"
    assert encode(Request(Command.STOP, 0)).hex() == "1234000000000000"
    assert encode(Request(Command.SET_BIAS, 0)).hex() == "1234004200000000"
    # netft_utils' pack() repeats the low 16 bits here; the manual's u32 does not
    assert encode(Request(Command.START_REALTIME, 0x12345678)).hex() == "1234000212345678"
    assert protocol.decode_request(bytes.fromhex("123400020000000a")) == Request(2, 10)


def test_record_golden_bytes_and_round_trip() -> None:
    """36 bytes: three u32 then six i32, big-endian; int32 extremes survive."""
    record = Record(1, 1000, 0, (1, -1, 1_000_000, -(2**31), 2**31 - 1, 0))
    golden = bytes.fromhex(
        "00000001" "000003e8" "00000000" "00000001" "ffffffff" "000f4240" "80000000" "7fffffff"
        "00000000"
    )
    assert protocol.encode_record(record) == golden
    assert protocol.decode_record(golden) == record


def test_calinfo_golden_bytes() -> None:
    """READCALINFO: 0x01 and 19 zeros; the reply is header, unit codes, u32 counts, 6 x u16."""
    assert protocol.encode_calinfo_request() == b"\x01" + bytes(19)
    reply = bytes.fromhex("1234" "02" "03" "000f4240" "000f4240" + "0001" * 6)
    assert protocol.encode_calinfo_reply(CalInfo(2, 3, 1_000_000, 1_000_000)) == reply
    assert protocol.decode_calinfo_reply(reply) == CalInfo(2, 3, 1_000_000, 1_000_000)
    assert isinstance(protocol.decode_calinfo_reply(reply[:23]), Rejected)
    assert protocol.decode_calinfo_reply(b"\x43\x21" + reply[2:]).reason == "CALINFO_HEADER"


def test_wrong_sizes_and_headers_are_rejected() -> None:
    """A datagram of 35 or 37 bytes is no record; a request needs header 0x1234."""
    record = protocol.encode_record(Record(1, 1, 0, (0,) * 6))
    assert protocol.decode_record(record[:-1]).reason == "RECORD_SIZE"
    assert protocol.decode_record(record + b"\0").reason == "RECORD_SIZE"
    assert protocol.decode_request(bytes.fromhex("4321000200000000")).reason == "REQUEST_HEADER"
    assert protocol.decode_request(b"\x12\x34").reason == "REQUEST_SIZE"


@given(st.binary(max_size=80))
def test_decoders_never_raise(data: bytes) -> None:
    """Any bytes from the wire decode to a message or a Rejected, never an exception."""
    for decode in (protocol.decode_record, protocol.decode_request,
                   protocol.decode_calinfo_reply):
        assert decode(data) is not None


def test_buffered_command_golden_bytes() -> None:
    """0x0003 start buffered streaming and 0x0041 reset threshold latch (manual Table 10.1)."""
    encode = protocol.encode_request
    assert encode(Request(Command.START_BUFFERED, 100)).hex() == "1234000300000064"
    assert encode(Request(Command.RESET_THRESHOLD_LATCH, 0)).hex() == "1234004100000000"


def test_a_buffered_datagram_is_records_back_to_back() -> None:
    """One datagram carries 1..40 records of 36 bytes; anything else is rejected, not raised."""
    records = [Record(i, 100 + i, 0, (i, -i, 0, 0, 0, i)) for i in range(1, 41)]
    data = protocol.encode_datagram(records)
    assert len(data) == 40 * 36 and data[:36] == protocol.encode_record(records[0])
    assert protocol.decode_datagram(data) == records
    assert protocol.decode_datagram(data[:36]) == records[:1]
    for bad in (b"", data[:35], data[:37], data + data[:36]):
        rejected = protocol.decode_datagram(bad)
        assert isinstance(rejected, Rejected) and rejected.reason == "DATAGRAM_SIZE"
