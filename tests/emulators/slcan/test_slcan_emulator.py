"""The emulated slcan adapter over a real pty, spoken to by python-can's own slcan interface."""

from __future__ import annotations

import itertools
import os
import time
from collections.abc import Iterator
from pathlib import Path

import can
import numpy as np
import pytest
import serial

from forcelearn.drivers.jr3_can.config import Jr3Config
from forcelearn.drivers.jr3_can.driver import Jr3CanSensor
from forcelearn.emulators.jr3 import Jr3EmulatorNode
from forcelearn.emulators.jr3.sensor_model import Jr3ModelParams
from forcelearn.emulators.physics.cell import CellPhysics
from forcelearn.emulators.slcan import SlcanAdapterEmulator
from forcelearn.emulators.slcan.adapter import FLAG_DATA_OVERRUN
from forcelearn.errors import SensorTimeout

_numbers = itertools.count()


@pytest.fixture
def channel() -> str:
    """A private virtual CAN channel (the adapter's bus side)."""
    return f"slcan-{os.getpid()}-{next(_numbers)}"


@pytest.fixture
def adapter(channel: str) -> Iterator[SlcanAdapterEmulator]:
    """A running emulated adapter on the channel; stopped (threads joined) after the test."""
    with SlcanAdapterEmulator(channel=channel) as emulator:
        yield emulator


@pytest.fixture
def peer(channel: str) -> Iterator[can.BusABC]:
    """Another node on the adapter's CAN bus."""
    with can.Bus(interface="virtual", channel=channel) as bus:
        yield bus


def _slcan(adapter: SlcanAdapterEmulator, bitrate: int = 1_000_000) -> can.BusABC:
    """python-can's slcan interface on the adapter's pty (no 2 s Arduino-reset wait)."""
    return can.Bus(interface="slcan", channel=adapter.address, bitrate=bitrate, sleep_after_open=0)


def test_python_can_identifies_the_adapter(adapter: SlcanAdapterEmulator) -> None:
    """get_version and get_serial_number parse the adapter's V and N replies."""
    with _slcan(adapter) as bus:
        assert bus.get_version(1.0) == (10, 13)
        assert bus.get_serial_number(1.0) == "FL01"
    deadline = time.monotonic() + 1.0  # shutdown's C is handled by the emulator's thread
    while adapter.model.is_open and time.monotonic() < deadline:
        time.sleep(0.005)
    assert adapter.model.bitrate == 1_000_000 and not adapter.model.is_open


def _fields(msg: can.Message | None) -> tuple[object, ...] | None:
    if msg is None:
        return None
    return (msg.arbitration_id, msg.is_extended_id, msg.is_remote_frame, msg.dlc, bytes(msg.data))


@pytest.mark.parametrize(
    "msg",
    [
        can.Message(arbitration_id=0x080, data=b"", is_extended_id=False),
        can.Message(arbitration_id=0x201, data=bytes.fromhex("C8001027 0000"),
                    is_extended_id=False),
        can.Message(arbitration_id=0x1ABCDEF0, data=bytes(range(8)), is_extended_id=True),
        can.Message(arbitration_id=0x7FF, is_remote_frame=True, dlc=3, is_extended_id=False),
    ],
    ids=["sync", "std", "ext", "remote"],
)
def test_frames_cross_the_adapter_both_ways(
    adapter: SlcanAdapterEmulator, peer: can.BusABC, msg: can.Message
) -> None:
    """A frame sent through slcan arrives on the bus, and the same frame comes back."""
    with _slcan(adapter) as host:
        host.send(msg)
        assert _fields(peer.recv(1.0)) == _fields(msg)
        peer.send(msg)
        assert _fields(host.recv(1.0)) == _fields(msg)


def test_the_jr3_driver_initialises_and_reads_through_slcan(
    adapter: SlcanAdapterEmulator, channel: str
) -> None:
    """The jr3 driver initialises and reads through slcan.

    Full scales, zeroed means and ~1 ms of sensor time per sample (7 or 8 frames of the counter: one
    answer per adapter loop turn), all through the LAWICEL pty.
    """
    model = Jr3ModelParams()
    with Jr3EmulatorNode(CellPhysics(), channel=channel, node_id=5, model=model, seed=3), \
            _slcan(adapter) as bus, \
            Jr3CanSensor(bus, Jr3Config(node_id=5, zero_on_init=True,
                                        stale_timeout_s=2.0)) as sensor:
        # (a long stale time: a loaded host's pty round trip must not pass for a lost answer)
        samples = sensor.read_many(400)
    assert sensor.full_scales is not None
    assert sensor.full_scales.tolist() == pytest.approx(list(model.full_scales), rel=1e-3)
    wrenches = np.array([s.wrench for s in samples])
    assert np.abs(wrenches[:, :3].mean(axis=0)).max() < 0.2  # zeroed: 1.5-3 N bias gone
    assert wrenches[:, :3].std(axis=0) == pytest.approx(model.noise_std[:3], rel=0.25)
    counters = np.array([s.counter for s in samples])
    assert set((np.diff(counters) % 65536).tolist()) <= {7, 8}
    assert sensor.stats.dropped_samples == 0
    assert adapter.model.frames_received >= 2 * 400


def test_a_wrong_bitrate_is_an_ack_timeout_for_the_driver(
    adapter: SlcanAdapterEmulator, channel: str
) -> None:
    """At 500 kbit/s on the 1 Mbit/s JR3 bus nothing passes: the driver times out."""
    with Jr3EmulatorNode(CellPhysics(), channel=channel) as node, \
            _slcan(adapter, bitrate=500_000) as bus:
        sensor = Jr3CanSensor(bus, Jr3Config(ack_timeout_s=0.1))
        with pytest.raises(SensorTimeout, match="bitrate"):
            sensor.initialise()
        sensor.close()
    assert node.stats.commands == 0


def test_a_host_that_stops_reading_loses_frames_but_never_stalls_the_adapter(
    adapter: SlcanAdapterEmulator, peer: can.BusABC
) -> None:
    """A full pty drops whole lines (overrun flag); frames keep flowing and stop() is prompt."""
    # read_until returns at its terminator; the long timeout only matters on a busy host,
    # where draining the frames still queued behind the overrun can take more than 0.5 s
    with serial.serial_for_url(adapter.address, timeout=5.0) as port:
        port.write(b"O\r")
        assert port.read_until(b"\r") == b"\r"
        frame = can.Message(arbitration_id=0x601, data=bytes(8), is_extended_id=False)
        deadline = time.monotonic() + 5.0
        while adapter.model.flags & FLAG_DATA_OVERRUN == 0 and time.monotonic() < deadline:
            for _ in range(500):
                peer.send(frame)
            time.sleep(0.01)
        assert adapter.model.flags & FLAG_DATA_OVERRUN, "the pty never filled"
        port.reset_input_buffer()  # may cut one line; every later one is whole
        port.write(b"F\r")
        lines = port.read_until(b"F").split(b"\r")
        assert lines[-1] == b"F"
        assert all(len(line) == len("t6018") + 16 for line in lines[1:-1])
    start = time.monotonic()
    adapter.close()
    assert time.monotonic() - start < 1.0
    assert not Path(adapter.address).exists()
