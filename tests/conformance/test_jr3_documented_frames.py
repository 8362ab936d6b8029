"""JR3 over CAN, documented frames in, decoded values out: our codec against the public documents.

Written from the adapter firmware's README (roboticslab-uc3m/jr3-mbed-firmware-can, "CAN
protocol" table and the ``cansend`` example), its ``main.cpp`` (op codes, payload layouts) and
the sensor layer's README (jr3-mbed-firmware: scaling). Expected values are the documents'
numbers, never our own encoder's output; frames are written out byte by byte here.
"""

from __future__ import annotations

import struct

import numpy as np
import pytest

from forcelearn.protocols.jr3_can import codec
from forcelearn.protocols.jr3_can.opcodes import DEFAULT_OPCODES
from forcelearn.protocols.jr3_can.scaling import counts_to_wrench, full_scales_from_wire

# The README's CAN protocol table: op code -> command, as printed there.
README_OPCODES = {
    0x080: "sync", 0x100: "ack", 0x180: "start_sync", 0x200: "start_async", 0x280: "stop",
    0x300: "zero_offsets", 0x380: "set_filter", 0x400: "get_state",
    0x480: "get_force_full_scales", 0x500: "get_moment_full_scales", 0x580: "reset",
    0x600: "forces", 0x680: "moments", 0x700: "bootup",
}


def _decode(can_id: int, data_hex: str) -> codec.Decoded:
    result = codec.decode(can_id, bytes.fromhex(data_hex))
    assert isinstance(result, codec.Decoded), result
    return result


def test_every_readme_opcode_is_in_our_default_map() -> None:
    """Our default opcode map is the README's table, op code for op code."""
    assert {code: kind for kind, code in DEFAULT_OPCODES.by_kind().items()} == README_OPCODES


def test_the_readmes_cansend_example_is_start_async_2_hz_10_ms_node_1() -> None:
    """The readmes cansend example is start async 2 hz 10 ms node 1.

    ``cansend can0 201#C80010270000``: "an ASYNC publisher on ID 1 with a period of 10 ms (10000 us
    = 0x2710) and a cutoff frequency of 2 Hz (200 Hz*0.01 = 0x00C8)".
    """
    result = _decode(0x201, "C80010270000")
    assert result.node_id == 1
    assert result.message == codec.StartAsync(cutoff_centi_hz=200, period_us=10_000)
    assert result.message.cutoff_centi_hz * 0.01 == pytest.approx(2.0)  # type: ignore[union-attr]
    assert codec.encode(codec.StartAsync(200, 10_000), 1) == (0x201, bytes.fromhex("C80010270000"))


def test_the_readmes_cutoff_example_1025_is_10_25_hz() -> None:
    """"cutoff frequency in 0.01*Hz (integer) (e.g. 1025 = 10.25 Hz)", 2 bytes, start sync."""
    result = _decode(0x185, struct.pack("<H", 1025).hex())
    assert (result.node_id, result.message) == (5, codec.StartSync(1025))


@pytest.mark.parametrize(
    ("can_id", "data_hex", "node", "expected"),
    [
        (0x080, "", 0, codec.Sync()),
        (0x101, "00", 1, codec.Ack(0)),  # "0x00 - sensor ready"
        (0x101, "01", 1, codec.Ack(1)),  # "0x01 - not initialized"
        (0x281, "", 1, codec.Stop()),
        (0x37F, "", 127, codec.ZeroOffsets()),
        (0x381, "E803", 1, codec.SetFilter(1000)),
        (0x401, "", 1, codec.GetState()),
        (0x481, "", 1, codec.GetForceFullScales()),
        (0x501, "", 1, codec.GetMomentFullScales()),
        (0x581, "", 1, codec.Reset()),
        (0x701, "", 1, codec.Bootup()),
    ],
)
def test_documented_commands_decode(
    can_id: int, data_hex: str, node: int, expected: codec.Message
) -> None:
    """Each row of the README's table, with its documented payload size."""
    result = _decode(can_id, data_hex)
    assert (result.node_id, result.message) == (node, expected)


def test_full_scale_acks_carry_three_uint16_after_the_state_byte() -> None:
    """"6 MSB bytes (optional)": forces in N, moments in dN*m (the host divides by 10)."""
    forces = _decode(0x101, "00" + struct.pack("<3H", 200, 200, 400).hex()).message
    moments = _decode(0x101, "00" + struct.pack("<3H", 200, 200, 200).hex()).message
    assert forces == codec.Ack(0, (200, 200, 400))
    assert moments == codec.Ack(0, (200, 200, 200))
    scales = full_scales_from_wire((200, 200, 400), (200, 200, 200))
    assert scales.tolist() == [200.0, 200.0, 400.0, 20.0, 20.0, 20.0]


def test_force_and_moment_frames_scale_as_the_readme_says() -> None:
    """Force and moment frames scale as the readme says.

    "(3x) 2 LSB bytes: Fx, Fy, Fz (integer, signed), 2 MSB bytes: frame counter"; value x full scale
    / 16384 for forces, / (16384 x 10) for moments with FS in dN*m.
    """
    forces = _decode(0x601, struct.pack("<3hH", 8192, -16384, 1, 65535).hex()).message
    moments = _decode(0x681, struct.pack("<3hH", 16384, -8192, 0, 65535).hex()).message
    assert forces == codec.Forces((8192, -16384, 1), 65535)
    assert moments == codec.Moments((16384, -8192, 0), 65535)
    scales = full_scales_from_wire((200, 200, 400), (200, 100, 50))
    wrench = counts_to_wrench(np.array([8192, -16384, 1, 16384, -8192, 0]), scales)
    expected = [8192 * 200 / 16384, -16384 * 200 / 16384, 400 / 16384,
                16384 * 200 / (16384 * 10), -8192 * 100 / (16384 * 10), 0.0]
    assert wrench.tolist() == pytest.approx(expected)


def test_sync_is_the_bare_opcode_and_a_node_id_on_it_is_not_sync() -> None:
    """SYNC is 0x080 exactly (main.cpp: ``msg.id == JR3_SYNC``); 0x081 is no documented frame."""
    assert _decode(0x080, "").message == codec.Sync()
    assert isinstance(codec.decode(0x081, b""), codec.Rejected)


def test_the_adapter_reads_short_fields_as_zero_and_ignores_extra_bytes() -> None:
    """The adapter reads short fields as zero and ignores extra bytes.

    main.cpp's parseCutOffFrequency / parseAsyncPeriod: a field whose bytes are not all in the
    payload reads 0; longer payloads are not refused. Our adapter-side decoder agrees.
    """
    as_adapter = codec.decode_as_adapter
    assert as_adapter(0x181, b"", 1) == codec.StartSync(0)
    assert as_adapter(0x181, b"\xc8", 1) == codec.StartSync(0)
    assert as_adapter(0x181, bytes.fromhex("C800FFFF"), 1) == codec.StartSync(200)
    assert as_adapter(0x201, bytes.fromhex("C800"), 1) == codec.StartAsync(200, 0)
    assert as_adapter(0x201, bytes.fromhex("C8001027"), 1) == codec.StartAsync(200, 0)
    assert as_adapter(0x201, bytes.fromhex("C80010270000AA"), 1) == codec.StartAsync(200, 10_000)
    assert as_adapter(0x281, b"\x01\x02", 1) == codec.Stop()
    assert as_adapter(0x080, b"\x01", 1) == codec.Sync()
    assert as_adapter(0x182, b"", 1) is None  # another node's command
    assert as_adapter(0x601, bytes(8), 1) is None  # its own data op code: "unsupported"
