"""The JR3-to-CAN adapter's opcode map, as a named and versioned table.

Every frame on the bus carries an 11-bit identifier ``opcode + node_id``
(node id 1..127), except SYNC, which is broadcast on the bare opcode. The
adapter firmware has changed its opcodes over time, so the codec never uses
a literal opcode: it looks the message kind up in an :class:`OpcodeMap`.

========================  ======  ===============  =====================================
kind                      opcode  direction        payload (little-endian)
========================  ======  ===============  =====================================
``sync``                  0x080   host -> all      none; id is exactly 0x080
``ack``                   0x100   sensor -> host   u8 status [+ 3 x u16 full scales]
``start_sync``            0x180   host -> sensor   u16 cut-off (0.01 Hz)
``start_async``           0x200   host -> sensor   u16 cut-off (0.01 Hz) + u32 period (us)
``stop``                  0x280   host -> sensor   none
``zero_offsets``          0x300   host -> sensor   none
``set_filter``            0x380   host -> sensor   u16 cut-off (0.01 Hz)
``get_state``             0x400   host -> sensor   none
``get_force_full_scales`` 0x480   host -> sensor   none (answered by a 7-byte ACK)
``get_moment_full_scales``0x500   host -> sensor   none (answered by a 7-byte ACK)
``reset``                 0x580   host -> sensor   none
``forces``                0x600   sensor -> host   3 x i16 Fx Fy Fz + u16 frame counter
``moments``               0x680   sensor -> host   3 x i16 Mx My Mz + u16 frame counter
``bootup``                0x700   sensor -> host   none (the host must initialise again)
========================  ======  ===============  =====================================
"""

from __future__ import annotations

import enum
from dataclasses import dataclass, fields
from functools import cached_property

NODE_ID_BITS = 0x7F
"""Low 7 bits of an identifier carry the node id; the opcode is a multiple of 0x80."""

SENSOR_FRAME_PERIOD_S = 128.5e-6
"""One complete 6-axis frame of the JR3 sensor as the adapter reads it, s (about 7.78 kHz):
the firmware's ``samplingPeriod`` (jr3-mbed-firmware, Jr3Controller.hpp)."""
ADAPTER_LOOP_PERIOD_S = 0.001
"""The adapter's main loop: it answers a pending SYNC and the queued commands once per turn,
then sleeps 1 ms (jr3-mbed-firmware-can, main.cpp)."""


class CounterMeaning(enum.Enum):
    """What the 16-bit frame counter of the force and moment frames counts, per firmware."""

    SENSOR_FRAMES = "sensor_frames"
    """Since 2023-12-27: complete sensor frames (~7.8 kHz) since streaming started; 0 on
    start, stop and reset; the difference of two counters is sensor time."""
    TRANSMITTED_SAMPLES = "transmitted_samples"
    """2023-09-25 .. 2023-12-26: one per force/moment pair sent; a gap is a lost sample."""


@dataclass(frozen=True)
class OpcodeMap:
    """One firmware version's opcodes (11-bit, multiples of 0x80)."""

    name: str
    version: str
    sync: int
    ack: int
    start_sync: int
    start_async: int
    stop: int
    zero_offsets: int
    set_filter: int
    get_state: int
    get_force_full_scales: int
    get_moment_full_scales: int
    reset: int
    forces: int
    moments: int
    bootup: int
    counter: CounterMeaning = CounterMeaning.SENSOR_FRAMES
    """What the frame counter counts with this firmware."""
    sensor_frame_period_s: float = SENSOR_FRAME_PERIOD_S
    """Sensor time per counter step (SENSOR_FRAMES), s."""
    loop_period_s: float = ADAPTER_LOOP_PERIOD_S
    """The adapter's main-loop period: at most one SYNC answered per turn, s."""

    def __post_init__(self) -> None:
        codes = self.by_kind()
        for kind, code in codes.items():
            if code & NODE_ID_BITS or not 0 < code <= 0x780:
                raise ValueError(f"opcode map {self.version}: {kind}={code:#x} is not 0x80..0x780")
        if len(set(codes.values())) != len(codes):
            raise ValueError(f"opcode map {self.version}: two kinds share an opcode")

    def by_kind(self) -> dict[str, int]:
        """Return ``{kind: opcode}`` for every message kind."""
        return {f.name: getattr(self, f.name) for f in fields(self) if f.type == "int"}

    @cached_property
    def kind_by_opcode(self) -> dict[int, str]:
        """The reverse table ``{opcode: kind}`` (kept on the map: hashing one costs more)."""
        return {code: kind for kind, code in self.by_kind().items()}


JR3_MBED_2023_12 = OpcodeMap(
    name="jr3-mbed-firmware CAN layer",
    version="2023-12",
    sync=0x080,
    ack=0x100,
    start_sync=0x180,
    start_async=0x200,
    stop=0x280,
    zero_offsets=0x300,
    set_filter=0x380,
    get_state=0x400,
    get_force_full_scales=0x480,
    get_moment_full_scales=0x500,
    reset=0x580,
    forces=0x600,
    moments=0x680,
    bootup=0x700,
)
"""The December 2023 opcode map of the open JR3-to-CAN adapter firmware (unchanged to 2026-02):
the counter counts sensor frames, one SYNC answered per 1 ms loop turn."""

OPCODE_MAPS: dict[str, OpcodeMap] = {JR3_MBED_2023_12.version: JR3_MBED_2023_12}
"""Known opcode maps by version string; add older firmware maps here."""

DEFAULT_OPCODES = JR3_MBED_2023_12
