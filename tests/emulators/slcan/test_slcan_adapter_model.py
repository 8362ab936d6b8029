"""The adapter's rules without I/O: open/close, bitrate, listen-only, flags, timestamps."""

from __future__ import annotations

from forcelearn.emulators.slcan.adapter import (
    FLAG_BUS_ERROR,
    FLAG_DATA_OVERRUN,
    FLAG_ERROR_PASSIVE,
    Outcome,
    SlcanAdapterModel,
)
from forcelearn.protocols import lawicel
from forcelearn.protocols.lawicel import BEL, CR, CanFrame, parse_line

FRAME = CanFrame(0x601, b"\x01\x02")


def _say(model: SlcanAdapterModel, line: bytes) -> lawicel.CanFrame | bytes:
    outcome = model.handle(parse_line(line))
    return outcome.to_bus if outcome.to_bus is not None else outcome.reply


def test_python_cans_open_sequence_then_frames_both_ways() -> None:
    """C, S8, empty, O, O (python-can sends O twice: the second is refused), then traffic."""
    model = SlcanAdapterModel(1_000_000)
    replies = [_say(model, line) for line in (b"C", b"S8", b"", b"O", b"O")]
    assert replies == [CR, CR, b"", CR, BEL]
    outcome = model.handle(parse_line(b"t6012" + b"0102"))
    assert outcome == Outcome(b"z\r", FRAME)
    assert model.from_bus(FRAME, now_ms=5) == b"t60120102\r"
    assert (model.frames_sent, model.frames_received) == (1, 1)


def test_closed_channel_refuses_frames_and_hears_nothing() -> None:
    """Before O: t is refused with BEL, F too, and bus frames are not passed on."""
    model = SlcanAdapterModel()
    assert _say(model, b"t0800") == BEL
    assert _say(model, b"F") == BEL
    assert model.from_bus(FRAME, 0) == b""
    assert model.errors == 2


def test_settings_change_only_while_closed() -> None:
    """S, s, Z and O are refused while open; C always succeeds (even twice)."""
    model = SlcanAdapterModel()
    assert _say(model, b"O") == CR
    assert [_say(model, line) for line in (b"S6", b"s031C", b"Z1", b"L")] == [BEL] * 4
    assert _say(model, b"C") == CR and _say(model, b"C") == CR
    assert _say(model, b"S6") == CR and model.bitrate == 500_000


def test_a_wrong_bitrate_passes_nothing_and_flags_bus_errors() -> None:
    """At 500 kbit/s on a 1 Mbit/s bus the frame is queued (z) but never sent; F reports it."""
    model = SlcanAdapterModel(1_000_000)
    for line in (b"S6", b"O"):
        _say(model, line)
    assert model.handle(parse_line(b"t0800")) == Outcome(b"z\r", None)
    assert model.from_bus(FRAME, 0) == b""
    assert _say(model, b"F") == lawicel.status_reply(FLAG_BUS_ERROR | FLAG_ERROR_PASSIVE)
    assert _say(model, b"F") == b"F00\r"  # read clears the flags


def test_listen_only_hears_but_never_sends() -> None:
    """L opens listen-only: bus frames reach the host, host frames are refused."""
    model = SlcanAdapterModel()
    assert _say(model, b"L") == CR
    assert _say(model, b"t0800") == BEL
    assert model.from_bus(FRAME, 0) == b"t60120102\r"


def test_timestamps_append_milliseconds_to_received_frames() -> None:
    """Z1 before O: every frame to the host ends with 4 hex digits of ms."""
    model = SlcanAdapterModel()
    _say(model, b"Z1")
    _say(model, b"O")
    assert model.from_bus(FRAME, now_ms=0x1234) == b"t601201021234\r"


def test_version_serial_and_overrun_flag() -> None:
    """V and N answer in any state; a lost line to the host raises the overrun flag."""
    model = SlcanAdapterModel(serial_number="AB12", hardware_version=1, software_version=2)
    assert _say(model, b"V") == b"V0102\r" and _say(model, b"N") == b"NAB12\r"
    _say(model, b"O")
    model.overrun()
    reply = _say(model, b"F")
    assert isinstance(reply, bytes) and int(reply[1:3], 16) & FLAG_DATA_OVERRUN
