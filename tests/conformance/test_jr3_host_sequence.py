"""Our JR3 driver's commands against the public host driver's (yarp-devices Jr3Mbed).

The adapter on the other end is not our emulator: a few lines here that answer as the
firmware README documents (an ACK to every bolded command, a 7-byte ACK to the full-scale
queries, a force and a moment frame to a SYNC), and record what the host sent. The expected
sequences are Jr3Mbed's ``initialize()`` / ``finalize()`` / ``notifyMessage()``
(ICanBusSharerImpl.cpp, Jr3Mbed.cpp): get state ("ping"), start sync (uint16 filter x 100)
or start async (+ uint32 period x 1e6), the two full-scale queries when none are configured,
a 0.1 s wait, zero offsets; stop on close; the whole initialisation again after a bootup
(ours: without the zero, and only once the cell says so).
"""

from __future__ import annotations

import collections
import itertools
import struct
from typing import Any

import can
import pytest

from forcelearn.drivers.jr3_can.config import Jr3Config
from forcelearn.drivers.jr3_can.driver import Jr3CanSensor
from forcelearn.errors import SensorRebooted

NODE = 1


class DocumentedAdapter(can.BusABC):
    """A bus with a JR3 adapter that answers as its README documents; records host frames."""

    def __init__(self, **kwargs: Any) -> None:
        self.sent: list[tuple[int, bytes]] = []
        self._rx: collections.deque[can.Message] = collections.deque()
        self._counter = 0
        self.channel_info = "documented JR3 adapter"
        super().__init__(channel="documented", **kwargs)

    def _reply(self, can_id: int, data: bytes) -> None:
        self._rx.append(can.Message(arbitration_id=can_id, data=data, is_extended_id=False))

    def bootup(self) -> None:
        """The adapter powered up again: 0x700 + node, no payload."""
        self._reply(0x700 + NODE, b"")

    def send(self, msg: can.Message, timeout: float | None = None) -> None:
        """Record the host's frame and queue the README's answer."""
        can_id, data = msg.arbitration_id, bytes(msg.data)
        self.sent.append((can_id, data))
        if can_id == 0x080:  # sync: force and moment data, one frame counter
            self._counter = (self._counter + 8) & 0xFFFF
            self._reply(0x600 + NODE, struct.pack("<3hH", 100, 200, 300, self._counter))
            self._reply(0x680 + NODE, struct.pack("<3hH", 10, 20, 30, self._counter))
        elif can_id & 0x7F == NODE:
            op = can_id & 0x780
            if op == 0x480:
                self._reply(0x100 + NODE, struct.pack("<B3H", 0, 200, 200, 400))
            elif op == 0x500:
                self._reply(0x100 + NODE, struct.pack("<B3H", 0, 200, 200, 200))
            elif op in (0x180, 0x200, 0x280, 0x300, 0x380, 0x400, 0x580):
                self._reply(0x100 + NODE, b"\x00")

    def _recv_internal(self, timeout: float | None) -> tuple[can.Message | None, bool]:
        return (self._rx.popleft() if self._rx else None), False


def _sensor(bus: DocumentedAdapter, **config: Any) -> Jr3CanSensor:
    config.setdefault("zero_settle_s", 0.0)
    config.setdefault("ack_timeout_s", 0.05)
    return Jr3CanSensor(bus, Jr3Config(**config))


def test_sync_initialisation_is_the_host_drivers_sequence() -> None:
    """Sync initialisation is the host drivers sequence.

    No full scales configured: ping, start sync (12500 = 125 Hz), forces, moments, zero; by default,
    as Jr3Mbed, which always zeroes. Close sends stop.
    """
    bus = DocumentedAdapter()
    with _sensor(bus, cutoff_hz=125.0):
        pass
    assert bus.sent == [
        (0x401, b""),
        (0x181, struct.pack("<H", 12500)),
        (0x481, b""),
        (0x501, b""),
        (0x301, b""),
        (0x281, b""),
    ]
    bus.shutdown()


def test_async_with_configured_full_scales_skips_the_queries() -> None:
    """Async with configured full scales skips the queries.

    Jr3Mbed with ``fullScales`` set and ``asyncPeriod`` 0.01 s, ``filter`` 2 Hz: ping, start async
    C8 00 10 27 00 00 (the README's example payload), zero; no full-scale query.
    """
    bus = DocumentedAdapter()
    sensor = _sensor(bus, mode="async", cutoff_hz=2.0, period_us=10_000,
                     full_scales=(200.0, 200.0, 400.0, 20.0, 20.0, 20.0))
    sensor.initialise()
    sensor.close()
    assert bus.sent == [
        (0x401, b""),
        (0x201, bytes.fromhex("C80010270000")),
        (0x301, b""),
        (0x281, b""),
    ]
    bus.shutdown()


def test_unfiltered_is_a_cutoff_of_zero_as_the_host_drivers_default() -> None:
    """Jr3Mbed's ``filter`` defaults to 0.0 Hz, sent as 0: the adapter's unfiltered data."""
    bus = DocumentedAdapter()
    with _sensor(bus, cutoff_hz=0.0):
        pass
    assert bus.sent[1] == (0x181, b"\x00\x00")
    bus.shutdown()


def test_a_bootup_frame_is_reported_and_the_host_initialises_again_without_zeroing() -> None:
    """On 0x700 + node Jr3Mbed runs initialize() again, zero included; ours departs on purpose.

    A zero taken where the tool presses hides the contact force: every
    read raises SensorRebooted until the cell, in free space, calls reinitialise(),
    which sends the same sequence without the zero (0x301); the cell zeroes then.
    """
    bus = DocumentedAdapter()
    with _sensor(bus) as sensor:
        sensor.read()
        bus.sent.clear()
        bus.bootup()
        with pytest.raises(SensorRebooted):
            sensor.read()
        sensor.reinitialise()
        sample = sensor.read()
        sent_ids = [can_id for can_id, _ in bus.sent]
    # (a SYNC may go out before the host has heard the bootup: it waits for that one in vain)
    start = sent_ids.index(0x401)
    assert sent_ids[:start] in ([], [0x080])
    assert sent_ids[start:start + 5] == [0x401, 0x181, 0x481, 0x501, 0x080]
    assert 0x301 not in sent_ids and sensor.stats.bootups == 1
    assert sample.wrench.tolist() == pytest.approx(
        [100 * 200 / 16384, 200 * 200 / 16384, 300 * 400 / 16384,
         10 * 200 / 163840, 20 * 200 / 163840, 30 * 200 / 163840])
    bus.shutdown()


def test_a_read_sends_one_sync_per_sample() -> None:
    """Each sample costs one SYNC: no SYNC is sent while one is still unanswered."""
    bus = DocumentedAdapter()
    with _sensor(bus) as sensor:
        bus.sent.clear()
        samples = sensor.read_many(20, window=8)
    assert [can_id for can_id, _ in bus.sent] == [0x080] * 20 + [0x281]
    steps = {b.counter - a.counter for a, b in itertools.pairwise(samples)}
    assert steps == {8}  # the counter's steps are the adapter's, never called losses
    assert sensor.stats.dropped_samples == 0
    bus.shutdown()
