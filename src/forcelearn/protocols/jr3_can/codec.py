"""Pure codec of the JR3-to-CAN adapter protocol: messages <-> (identifier, payload).

No bus, no threads: :func:`encode` turns a message into a :class:`Frame`, and
:func:`decode` turns any identifier and payload into either a :class:`Decoded`
message or a :class:`Rejected` result naming why. :func:`decode` never raises,
whatever it is given, so the driver and the emulator can count bad frames and
go on. Payloads are little-endian; layouts are in :mod:`.opcodes`.

Wire units are kept here (cut-off in 0.01 Hz, period in us, raw 16-bit counts);
conversion to physical units belongs to :mod:`.scaling`.
"""

from __future__ import annotations

import enum
import struct
from dataclasses import dataclass
from typing import ClassVar, NamedTuple

from forcelearn.protocols.jr3_can.opcodes import (
    DEFAULT_OPCODES,
    NODE_ID_BITS,
    OpcodeMap,
)

MAX_STANDARD_ID = 0x7FF
COUNTER_MODULUS = 1 << 16
ACK_READY = 0
ACK_NOT_INITIALISED = 1

_U16 = struct.Struct("<H")
_U16_U32 = struct.Struct("<HI")
_ACK_FULL = struct.Struct("<B3H")
_AXES = struct.Struct("<3hH")


@dataclass(frozen=True, slots=True)
class Sync:
    """Host -> all: sample now (sync mode); one force and one moment frame answer."""

    kind: ClassVar[str] = "sync"


SYNC = Sync()
"""The one SYNC (it has no fields): what senders send, what the adapter hears."""


@dataclass(frozen=True, slots=True)
class Ack:
    """Sensor -> host: status (0 ready, 1 not initialised), optional 3 full scales.

    Full scales are in N for forces and dN*m for moments, as the adapter sends them.
    """

    status: int = ACK_READY
    full_scales: tuple[int, int, int] | None = None
    kind: ClassVar[str] = "ack"

    @property
    def ready(self) -> bool:
        """True when the adapter reports itself initialised."""
        return self.status == ACK_READY


@dataclass(frozen=True, slots=True)
class StartSync:
    """Host -> sensor: enter sync mode with a low-pass cut-off in 0.01 Hz."""

    cutoff_centi_hz: int
    kind: ClassVar[str] = "start_sync"


@dataclass(frozen=True, slots=True)
class StartAsync:
    """Host -> sensor: stream every ``period_us`` with a cut-off in 0.01 Hz."""

    cutoff_centi_hz: int
    period_us: int
    kind: ClassVar[str] = "start_async"


@dataclass(frozen=True, slots=True)
class SetFilter:
    """Host -> sensor: change the low-pass cut-off (0.01 Hz)."""

    cutoff_centi_hz: int
    kind: ClassVar[str] = "set_filter"


@dataclass(frozen=True, slots=True)
class Stop:
    """Host -> sensor: stop sampling."""

    kind: ClassVar[str] = "stop"


@dataclass(frozen=True, slots=True)
class ZeroOffsets:
    """Host -> sensor: store the present reading as the offset."""

    kind: ClassVar[str] = "zero_offsets"


@dataclass(frozen=True, slots=True)
class GetState:
    """Host -> sensor: ask for the adapter status (answered by an ACK)."""

    kind: ClassVar[str] = "get_state"


@dataclass(frozen=True, slots=True)
class GetForceFullScales:
    """Host -> sensor: ask for the force full scales (answered by a 7-byte ACK, N)."""

    kind: ClassVar[str] = "get_force_full_scales"


@dataclass(frozen=True, slots=True)
class GetMomentFullScales:
    """Host -> sensor: ask for the moment full scales (answered by a 7-byte ACK, dN*m)."""

    kind: ClassVar[str] = "get_moment_full_scales"


@dataclass(frozen=True, slots=True)
class Reset:
    """Host -> sensor: reset the adapter."""

    kind: ClassVar[str] = "reset"


@dataclass(frozen=True, slots=True)
class Forces:
    """Sensor -> host: raw Fx, Fy, Fz counts (16384 = full scale) and the frame counter."""

    raw: tuple[int, int, int]
    counter: int
    kind: ClassVar[str] = "forces"


@dataclass(frozen=True, slots=True)
class Moments:
    """Sensor -> host: raw Mx, My, Mz counts (16384 = full scale) and the frame counter."""

    raw: tuple[int, int, int]
    counter: int
    kind: ClassVar[str] = "moments"


@dataclass(frozen=True, slots=True)
class Bootup:
    """Sensor -> host: the adapter (re)started; the host must initialise again."""

    kind: ClassVar[str] = "bootup"


Message = (
    Sync | Ack | StartSync | StartAsync | SetFilter | Stop | ZeroOffsets | GetState
    | GetForceFullScales | GetMomentFullScales | Reset | Forces | Moments | Bootup
)
_EMPTY_KINDS: dict[str, Message] = {
    m.kind: m
    for m in (SYNC, Stop(), ZeroOffsets(), GetState(), GetForceFullScales(),
              GetMomentFullScales(), Reset(), Bootup())
}


class Frame(NamedTuple):
    """An 11-bit identifier and its payload, ready for a CAN frame."""

    arbitration_id: int
    data: bytes


class RejectReason(enum.Enum):
    """Why :func:`decode` refused a frame."""

    EXTENDED_ID = "29-bit identifier"
    ID_OUT_OF_RANGE = "identifier above 0x7FF"
    UNKNOWN_OPCODE = "unknown opcode"
    BAD_NODE_ID = "node id 0 on an addressed opcode, or a node id on SYNC"
    BAD_LENGTH = "payload length wrong for the opcode"


@dataclass(frozen=True, slots=True)
class Decoded:
    """A valid frame: the node id it came from or went to (0 for SYNC) and its message."""

    node_id: int
    message: Message


@dataclass(frozen=True, slots=True)
class Rejected:
    """A malformed frame, kept for counting and logging."""

    reason: RejectReason
    arbitration_id: int
    data: bytes


def _check_u16(name: str, value: int) -> None:
    if not 0 <= value <= 0xFFFF:
        raise ValueError(f"{name}={value} does not fit a uint16 (0..65535)")


def _ack_payload(message: Ack) -> bytes:
    if not 0 <= message.status <= 0xFF:
        raise ValueError(f"ACK status={message.status} does not fit a byte")
    if message.full_scales is None:
        return bytes((message.status,))
    for value in message.full_scales:
        _check_u16("full scale", value)
    return _ACK_FULL.pack(message.status, *message.full_scales)


def _cutoff_payload(message: StartSync | SetFilter) -> bytes:
    _check_u16("cutoff_centi_hz", message.cutoff_centi_hz)
    return _U16.pack(message.cutoff_centi_hz)


def _start_async_payload(message: StartAsync) -> bytes:
    _check_u16("cutoff_centi_hz", message.cutoff_centi_hz)
    if not 0 <= message.period_us <= 0xFFFFFFFF:
        raise ValueError(f"period_us={message.period_us} does not fit a uint32")
    return _U16_U32.pack(message.cutoff_centi_hz, message.period_us)


def _axes_payload(message: Forces | Moments) -> bytes:
    try:
        return _AXES.pack(*message.raw, message.counter)
    except struct.error as exc:
        raise ValueError(f"raw counts {message.raw} or counter {message.counter} do not fit "
                         "int16 / uint16") from exc


_PAYLOAD = {
    "ack": _ack_payload,
    "start_sync": _cutoff_payload,
    "set_filter": _cutoff_payload,
    "start_async": _start_async_payload,
    "forces": _axes_payload,
    "moments": _axes_payload,
}
"""Kinds with a payload -> their packer; every other kind has none."""


def encode(message: Message, node_id: int, opcodes: OpcodeMap = DEFAULT_OPCODES) -> Frame:
    """Return the frame of ``message`` for node ``node_id`` (1..127; ignored for SYNC).

    Raises ValueError for a node id or field out of its wire range.
    """
    opcode = getattr(opcodes, message.kind)
    if message.kind == "sync":
        return Frame(opcode, b"")
    if not 1 <= node_id <= NODE_ID_BITS:
        raise ValueError(f"node_id={node_id} is not 1..127")
    packer = _PAYLOAD.get(message.kind)
    return Frame(opcode + node_id, b"" if packer is None else packer(message))  # type: ignore[operator]


def decode(
    arbitration_id: int,
    data: bytes | bytearray,
    *,
    is_extended_id: bool = False,
    opcodes: OpcodeMap = DEFAULT_OPCODES,
) -> Decoded | Rejected:
    """Decode one frame; never raises, returns :class:`Rejected` for anything malformed."""
    if is_extended_id:
        return Rejected(RejectReason.EXTENDED_ID, arbitration_id, bytes(data))
    if not 0 <= arbitration_id <= MAX_STANDARD_ID:
        return Rejected(RejectReason.ID_OUT_OF_RANGE, arbitration_id, bytes(data))
    node_id = arbitration_id & NODE_ID_BITS
    kind = opcodes.kind_by_opcode.get(arbitration_id - node_id)
    if kind is None:
        return Rejected(RejectReason.UNKNOWN_OPCODE, arbitration_id, bytes(data))
    if (node_id == 0) != (kind == "sync"):
        return Rejected(RejectReason.BAD_NODE_ID, arbitration_id, bytes(data))
    message = _parse(kind, data)  # parses bytes and bytearray alike, without a copy
    if message is None:
        return Rejected(RejectReason.BAD_LENGTH, arbitration_id, bytes(data))
    return Decoded(node_id, message)


def _parse(kind: str, data: bytes | bytearray) -> Message | None:
    """Parse a payload of a known kind; None when its length is wrong."""
    size = len(data)
    if kind in _EMPTY_KINDS:
        return _EMPTY_KINDS[kind] if size == 0 else None
    if kind == "forces" or kind == "moments":
        if size != _AXES.size:
            return None
        fx, fy, fz, counter = _AXES.unpack(data)
        cls = Forces if kind == "forces" else Moments
        return cls((fx, fy, fz), counter)
    if kind == "ack":
        if size == 1:
            return Ack(data[0])
        if size == _ACK_FULL.size:
            status, a, b, c = _ACK_FULL.unpack(data)
            return Ack(status, (a, b, c))
        return None
    if kind == "start_async":
        if size != _U16_U32.size:
            return None
        cutoff, period = _U16_U32.unpack(data)
        return StartAsync(cutoff, period)
    # start_sync, set_filter
    if size != _U16.size:
        return None
    (cutoff,) = _U16.unpack(data)
    return StartSync(cutoff) if kind == "start_sync" else SetFilter(cutoff)


_SENSOR_TO_HOST = frozenset({"ack", "forces", "moments", "bootup"})


def _field(data: bytes | bytearray, offset: int, layout: struct.Struct) -> int:
    """One little-endian field, or 0 when the payload does not hold all of its bytes."""
    if len(data) < offset + layout.size:
        return 0
    (value,) = layout.unpack_from(data, offset)
    return int(value)


_U32 = struct.Struct("<I")


def decode_as_adapter(
    arbitration_id: int,
    data: bytes | bytearray,
    node_id: int,
    *,
    is_extended_id: bool = False,
    opcodes: OpcodeMap = DEFAULT_OPCODES,
) -> Message | None:
    """What the adapter firmware makes of a frame it hears: SYNC, a command for it, or None.

    As jr3-mbed-firmware-can's ``main.cpp``: SYNC is the exact identifier of the
    ``sync`` opcode, whatever its payload; any other frame is for this node when
    the identifier's low 7 bits are ``node_id``, and is dispatched on its opcode.
    Lengths are not enforced: a field whose bytes are not all there reads 0 (a
    start with no payload is unfiltered; a start async without its 4 period bytes
    has period 0) and extra bytes are ignored. Opcodes the adapter does not act on
    (its own ACK, data and bootup codes, unknown ones) give None, as it ignores them.
    """
    if is_extended_id or not 0 <= arbitration_id <= MAX_STANDARD_ID:
        return None
    if arbitration_id == opcodes.sync:
        return SYNC
    if arbitration_id & NODE_ID_BITS != node_id:
        return None
    kind = opcodes.kind_by_opcode.get(arbitration_id & ~NODE_ID_BITS & MAX_STANDARD_ID)
    if kind is None or kind in _SENSOR_TO_HOST or kind == "sync":
        return None
    if kind == "start_sync":
        return StartSync(_field(data, 0, _U16))
    if kind == "set_filter":
        return SetFilter(_field(data, 0, _U16))
    if kind == "start_async":
        return StartAsync(_field(data, 0, _U16), _field(data, _U16.size, _U32))
    return _EMPTY_KINDS[kind]
