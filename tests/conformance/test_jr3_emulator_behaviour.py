"""Our JR3 adapter emulator against the adapter firmware's documented behaviour.

Sources: jr3-mbed-firmware-can ``main.cpp`` (the main loop: a SYNC sets a flag answered once
per turn, then the queued commands, then ``sleep_for(1ms)``; reset re-initialises and ACKs
with no bootup; bootup only after the power-up initialisation) and jr3-mbed-firmware
``Jr3Controller.cpp`` (``frameCounter++`` once per complete 6-axis frame,
``samplingPeriod = 128.5e-6``; ``stopSensorThread`` sets the counter to 0 and the offsets
live in the sensor thread; cut-off 0 gives ``smoothingFactor = 1``, unfiltered; the
initialisation reads 256 EEPROM bytes). Frames are written and read by hand (struct), and
time is the emulated cell's simulated clock, read after each exchange.
"""

from __future__ import annotations

import itertools
import os
import struct
from collections.abc import Iterator

import can
import numpy as np
import pytest

from forcelearn.emulators.jr3 import Jr3EmulatorNode
from forcelearn.emulators.jr3.sensor_model import Jr3ModelParams
from forcelearn.emulators.physics.cell import CellPhysics

FRAME_S = 128.5e-6
"""Jr3Controller.hpp: ``samplingPeriod = 128.5e-6f``, one complete sensor frame."""
LOOP_S = 0.001
"""main.cpp: ``rtos::ThisThread::sleep_for(1ms)`` at the end of every turn."""
EEPROM_S = 256 * FRAME_S
"""initialize(): 256 calibration bytes, one per sensor frame (our reading of the stream)."""
BIAS = (1.5, -2.0, 3.0, 0.05, -0.08, 0.03)
QUIET = Jr3ModelParams(noise_std=(0.0,) * 6, bias_drift_per_sqrt_s=(0.0,) * 6,
                          initial_bias=BIAS)
_numbers = itertools.count()


@pytest.fixture
def physics() -> CellPhysics:
    """A free-space cell (its clock is the emulator's simulated time)."""
    return CellPhysics()


def _node(physics: CellPhysics, **kwargs: object) -> tuple[Jr3EmulatorNode, can.BusABC]:
    channel = f"conf-jr3-{os.getpid()}-{next(_numbers)}"
    node = Jr3EmulatorNode(physics, channel=channel, in_process=True, **kwargs)  # type: ignore[arg-type]
    return node, can.Bus(interface="forcelearn-jr3", channel=channel)


@pytest.fixture
def quiet(physics: CellPhysics) -> Iterator[tuple[Jr3EmulatorNode, can.BusABC]]:
    """A node on node id 1 with a noise-free sensor of known bias, and the host's bus."""
    node, bus = _node(physics, model=QUIET)
    yield node, bus
    bus.shutdown()
    node.close()


@pytest.fixture
def noisy(physics: CellPhysics) -> Iterator[tuple[Jr3EmulatorNode, can.BusABC]]:
    """A node with the default (noisy) sensor model."""
    node, bus = _node(physics, seed=5)
    yield node, bus
    bus.shutdown()
    node.close()


def _send(bus: can.BusABC, can_id: int, data: bytes = b"") -> None:
    bus.send(can.Message(arbitration_id=can_id, data=data, is_extended_id=False))


def _drain(bus: can.BusABC) -> list[tuple[int, bytes]]:
    """Everything the adapter sends while the host waits (the in-process bus runs its turns)."""
    out = []
    while (msg := bus.recv(0)) is not None:
        out.append((msg.arbitration_id, bytes(msg.data)))
    return out


def _pairs(frames: list[tuple[int, bytes]]) -> list[tuple[tuple[int, ...], int]]:
    """(six raw counts, counter) of each force frame followed by its moment frame."""
    out = []
    for (fid, fdata), (mid, mdata) in itertools.pairwise(frames):
        if fid == 0x601 and mid == 0x681:
            *forces, counter = struct.unpack("<3hH", fdata)
            *moments, counter_m = struct.unpack("<3hH", mdata)
            assert counter == counter_m
            out.append(((*forces, *moments), counter))
    return out


def _sync_pair(bus: can.BusABC) -> tuple[tuple[int, ...], int]:
    _send(bus, 0x080)
    pairs = _pairs(_drain(bus))
    assert len(pairs) == 1
    return pairs[0]


def test_get_state_is_a_one_byte_ack_ready_from_power_up(quiet: tuple) -> None:
    """Get state is a one byte ack ready from power up.

    "The get state command is a no-op that can be used to ping the controller"; ready (0x00) once
    the power-up initialisation succeeded, before any start.
    """
    _, bus = quiet
    _send(bus, 0x401)
    assert _drain(bus) == [(0x101, b"\x00")]


def test_the_counter_counts_sensor_frames_at_128_5_us(
    quiet: tuple, physics: CellPhysics
) -> None:
    """The counter counts sensor frames at 128 5 us.

    Δcounter / Δtime is the sensor's frame rate (1 / 128.5 µs = 7782 Hz), whatever the host asks
    for; it wraps at 65536.
    """
    _, bus = quiet
    _send(bus, 0x181, struct.pack("<H", 12500))
    assert _drain(bus) == [(0x101, b"\x00")]
    times, counters = [], []
    for _ in range(300):
        _, counter = _sync_pair(bus)
        times.append(physics.clock.now_s)
        counters.append(counter)
    unwrapped = np.unwrap(np.array(counters, dtype=float), period=65536)
    rate = (unwrapped[-1] - unwrapped[0]) / (times[-1] - times[0])
    assert rate == pytest.approx(1 / FRAME_S, rel=0.01)
    assert counters[0] < 100  # from 0 at the start


def test_one_answer_per_loop_turn_however_many_syncs(quiet: tuple, physics: CellPhysics) -> None:
    """One answer per loop turn however many syncs.

    A SYNC only sets a flag; each 1 ms turn answers it once: 5 SYNCs sent within one turn get one
    pair, and a burst of SYNCs over several ms gets at most one pair per ms.
    """
    _, bus = quiet
    _send(bus, 0x181, struct.pack("<H", 12500))
    _drain(bus)
    start = physics.clock.now_s
    for _ in range(5):
        _send(bus, 0x080)
    assert physics.clock.now_s - start < LOOP_S / 2  # all five inside one turn
    assert len(_pairs(_drain(bus))) == 1
    start = physics.clock.now_s
    for _ in range(100):  # ~5.5 ms of SYNCs back to back on the bus
        _send(bus, 0x080)
    frames = _drain(bus)
    span_ms = (physics.clock.now_s - start) / LOOP_S
    answered = len(_pairs(frames))
    assert 1 <= answered <= span_ms + 1 and answered < 100


def test_sync_is_answered_in_async_mode_too(quiet: tuple, physics: CellPhysics) -> None:
    """main.cpp answers the SYNC flag whenever the sensor runs (``acquire``), async included."""
    _, bus = quiet
    _send(bus, 0x201, struct.pack("<HI", 200, 1_000_000))  # async, 1 s period
    frames = _drain(bus)
    assert (0x101, b"\x00") in frames
    _send(bus, 0x080)
    assert len(_pairs(_drain(bus))) == 1


def test_stop_clears_the_counter_and_the_offsets(quiet: tuple) -> None:
    """Stop clears the counter and the offsets.

    stopSensorThread: counter := 0, and the offsets (local to the sensor thread) are lost; so after
    stop and start the raw bias is back and the counter counts from 0 again.
    """
    _, bus = quiet
    _send(bus, 0x181)  # no payload: cut-off 0, unfiltered
    _drain(bus)
    raw, _ = _sync_pair(bus)
    assert raw[0] == round(BIAS[0] * 16384 / 200)  # the bias, not zeroed at power-up
    _send(bus, 0x301)
    _drain(bus)
    for _ in range(50):
        raw, counter_before = _sync_pair(bus)
    assert raw == (0,) * 6 and counter_before > 300
    _send(bus, 0x281)
    assert _drain(bus) == [(0x101, b"\x00")]
    _send(bus, 0x181)
    _drain(bus)
    raw, counter = _sync_pair(bus)
    assert raw[0] == round(BIAS[0] * 16384 / 200) and counter < 20


def test_reset_blocks_for_the_eeprom_then_acks_ready_with_no_bootup(
    quiet: tuple, physics: CellPhysics
) -> None:
    """Reset blocks for the eeprom then acks ready with no bootup.

    RESET: the loop re-reads 256 EEPROM bytes, then ACKs ready; no bootup frame (0x701) is sent, the
    sensor is stopped (a SYNC gets nothing) and the counter restarts from 0.
    """
    _, bus = quiet
    _send(bus, 0x181, struct.pack("<H", 12500))
    _drain(bus)
    for _ in range(20):
        _sync_pair(bus)
    sent_at = physics.clock.now_s
    _send(bus, 0x581)
    assert _drain(bus) == [(0x101, b"\x00")]
    assert physics.clock.now_s - sent_at >= EEPROM_S
    _send(bus, 0x080)
    assert _drain(bus) == []
    _send(bus, 0x181, struct.pack("<H", 12500))
    _drain(bus)
    _, counter = _sync_pair(bus)
    assert counter < 20


def test_bootup_only_at_power_up(quiet: tuple) -> None:
    """The bootup frame (0x700 + node, empty) is sent after the power-up initialisation."""
    node, bus = quiet
    assert _drain(bus) == []  # the host listens (joins the bus) before the power cycle
    node.inject_bootup()
    assert _drain(bus) == [(0x701, b"")]


def test_payload_lengths_are_lenient(quiet: tuple) -> None:
    """Payload lengths are lenient.

    Missing bytes read 0 and extra bytes are ignored: a start with one byte is unfiltered, a set
    filter with 4 bytes takes the first two, a stop with a payload stops.
    """
    node, bus = quiet
    _send(bus, 0x181, b"\x10")
    assert _drain(bus) == [(0x101, b"\x00")]
    assert node.cutoff_hz == 0.0
    _send(bus, 0x381, struct.pack("<H", 1025) + b"\xff\xff")
    assert _drain(bus) == [(0x101, b"\x00")]
    assert node.cutoff_hz == pytest.approx(10.25)
    _send(bus, 0x281, b"\x01\x02\x03")
    assert _drain(bus) == [(0x101, b"\x00")]
    _send(bus, 0x080)
    assert _drain(bus) == []


def test_cutoff_zero_is_unfiltered(noisy: tuple) -> None:
    """Cutoff zero is unfiltered.

    SmoothingFactor = 1 at cut-off 0: samples 1 ms apart share no noise, while a 10 Hz low-pass
    (time constant 16 ms) makes them nearly equal.
    """
    _, bus = noisy

    def lag1(cutoff_centi_hz: int) -> float:
        _send(bus, 0x181, struct.pack("<H", cutoff_centi_hz))
        _drain(bus)
        fy = np.array([_sync_pair(bus)[0][1] for _ in range(400)], dtype=float)[50:]
        _send(bus, 0x281)
        _drain(bus)
        return float(np.corrcoef(fy[:-1], fy[1:])[0, 1])

    assert abs(lag1(0)) < 0.15
    assert lag1(1000) > 0.8
