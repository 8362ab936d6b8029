"""The in-process routes: ``forcelearn-robot://`` (pyserial) and ``forcelearn-jr3`` (python-can).

They must carry the same bytes as the pty and the virtual bus (the same
answers, the same simulated times) and fail the way a port or a bus does.
"""

from __future__ import annotations

import itertools
import os
import time

import can
import numpy as np
import pytest
import serial

from forcelearn.devices import Pose
from forcelearn.drivers.computer_link import ComputerLinkRobot, LinkConfig
from forcelearn.drivers.jr3_can.config import Jr3Config
from forcelearn.drivers.jr3_can.driver import Jr3CanSensor
from forcelearn.emulators import registry
from forcelearn.emulators.computer_link import ComputerLinkEmulator
from forcelearn.emulators.jr3 import Jr3EmulatorNode
from forcelearn.emulators.physics.arm import HOME
from forcelearn.emulators.physics.cell import CellPhysics
from forcelearn.emulators.physics.sponge import Sponge
from forcelearn.errors import LinkError, SensorBusError

FAST = {"ack_timeout_s": 0.2, "reply_timeout_s": 0.2}
_numbers = itertools.count()


def _name(stem: str) -> str:
    return f"{stem}-{os.getpid()}-{next(_numbers)}"


# ---- forcelearn-robot:// -------------------------------------------------------------

def test_a_named_controller_is_reached_with_serial_for_url() -> None:
    """The driver opens the emulator's URL and a move executes on it."""
    with ComputerLinkEmulator("inproc", name=_name("robot")) as emulator:
        assert emulator.address.startswith("forcelearn-robot://")
        with ComputerLinkRobot(LinkConfig(url=emulator.address, **FAST)) as robot:
            robot.move_by(dz_mm=-5.0)
            robot.wait_in_position(5.0)
            assert emulator.move_count == 1
            assert robot.read_pose().z_mm == pytest.approx(HOME.z_mm - 5.0, abs=0.2)


def test_the_same_exchange_gives_the_same_answers_and_times_as_a_pty() -> None:
    """Statuses and the controller's clock agree, exchange by exchange, with the pty route."""

    def session(transport: str) -> list[tuple[object, ...]]:
        with ComputerLinkEmulator(transport) as emulator, \
                ComputerLinkRobot(LinkConfig(url=emulator.address)) as robot:
            seen = []
            for step in range(3):
                robot.move_by(dy_mm=2.0 + step, dz_mm=-5.0)
                for _ in range(6):
                    status = robot.read_status()
                    seen.append((status.moving, status.in_position, status.time_s))
                seen.append(tuple(robot.read_pose().position_mm))
            return seen

    assert session("inproc") == session("pty")


def test_a_private_controller_needs_no_name_and_stops_with_its_port() -> None:
    """``forcelearn-robot://?instant=1`` starts its own emulator; closing the port stops it."""
    before = registry.names("robot")
    with ComputerLinkRobot(LinkConfig(url="forcelearn-robot://?instant=1", **FAST)) as robot:
        assert len(registry.names("robot")) == len(before) + 1
        robot.move_to(Pose(900.0, 10.0, 600.0, HOME.quaternion))
        assert robot.read_status().in_position  # instant arm: there at once
    assert registry.names("robot") == before


@pytest.mark.parametrize(
    ("url", "words"),
    [
        ("forcelearn-robot://nobody-here", "no in-process robot controller emulator named"),
        ("forcelearn-robot://?speed=3", "unknown option"),
        ("forcelearn-robot://x?instant=1", "private emulator"),
    ],
)
def test_bad_urls_are_refused_with_what_to_do(url: str, words: str) -> None:
    """A wrong name or option is a SerialException naming the fix, before any byte moves."""
    with pytest.raises(serial.SerialException, match=words):
        serial.serial_for_url(url)


def test_one_client_at_a_time() -> None:
    """A second open is refused while the first holds the port; after it closes, it succeeds."""
    with ComputerLinkEmulator("inproc") as emulator:
        first = serial.serial_for_url(emulator.address, timeout=0.1)
        with pytest.raises(serial.SerialException, match="another client"):
            serial.serial_for_url(emulator.address, timeout=0.1)
        first.close()
        second = serial.serial_for_url(emulator.address, timeout=0.1)
        second.close()


def test_a_stopped_controller_fails_the_driver_with_a_link_error() -> None:
    """Writing to a controller that has stopped is a lost port, not a hang."""
    emulator = ComputerLinkEmulator("inproc")
    emulator.start()
    robot = ComputerLinkRobot(LinkConfig(url=emulator.address, **FAST))
    emulator.close()
    t0 = time.monotonic()
    with pytest.raises(LinkError):
        robot.read_status()
    assert time.monotonic() - t0 < 2.0
    robot.close()


def test_a_read_with_no_answer_coming_waits_its_timeout() -> None:
    """Nothing written, nothing to read: ``read`` returns empty after its timeout, like a port."""
    with ComputerLinkEmulator("inproc") as emulator:
        port = serial.serial_for_url(emulator.address, timeout=0.05)
        t0 = time.monotonic()
        assert port.read(1) == b""
        assert time.monotonic() - t0 >= 0.04
        port.close()


# ---- forcelearn-jr3 ------------------------------------------------------------------

def _quiet(**extra: object) -> dict[str, object]:
    zeros = [0.0] * 6
    return {"noise_std": zeros, "initial_bias": zeros, "bias_drift_per_sqrt_s": zeros, **extra}


def test_can_bus_interface_gives_an_emulated_adapter_with_the_given_model() -> None:
    """``can.Bus(interface="forcelearn-jr3")`` alone gives a JR3; model options take effect."""
    with can.Bus(interface="forcelearn-jr3", channel=_name("jr3"), **_quiet()) as bus, \
            Jr3CanSensor(bus, Jr3Config(zero_settle_s=0.0)) as sensor:
        samples = sensor.read_many(10)
    # free space, point tool, no noise, no bias: exactly zero
    assert all(not s.wrench.any() for s in samples)
    # one sample per adapter loop turn (1 ms): 7 or 8 sensor frames of 128.5 µs apart
    assert {(b.counter - a.counter) % 65536
            for a, b in itertools.pairwise(samples)} <= {7, 8}


def test_a_bus_joins_the_node_of_its_channel_and_reads_the_cell_behind_it() -> None:
    """A node started for a cell is what the bus reaches (it reads that cell's contact)."""
    channel = _name("cell")
    physics = CellPhysics(Sponge(), Pose(900.0, 0.0, 0.0, HOME.quaternion))
    node = Jr3EmulatorNode(physics, channel=channel, in_process=True, seed=3)
    try:
        with can.Bus(interface="forcelearn-jr3", channel=channel) as bus, \
                Jr3CanSensor(bus, Jr3Config(zero_settle_s=0.0)) as sensor:
            sensor.read_many(5)
            assert node.hosts == 1 and node.stats.samples >= 5
    finally:
        node.close()
    assert registry.lookup("jr3", channel) is None


def test_the_same_samples_as_on_the_virtual_bus() -> None:
    """Same seed, same cell: the in-process route reads exactly what the virtual bus reads."""

    def read(route: str) -> np.ndarray:
        channel = _name(route)
        physics = CellPhysics(Sponge(), Pose(900.0, 3.0, 0.0, HOME.quaternion))
        node = Jr3EmulatorNode(physics, channel=channel, seed=11,
                               in_process=route == "forcelearn-jr3")
        try:
            with can.Bus(interface=route, channel=channel) as bus, \
                    Jr3CanSensor(bus, Jr3Config(zero_settle_s=0.0)) as sensor:
                wrenches = np.array([s.wrench for s in sensor.read_many(40)])
                return np.concatenate([wrenches.ravel(), [physics.clock.now_s]])
        finally:
            node.close()

    assert np.array_equal(read("forcelearn-jr3"), read("virtual"))


def test_buses_on_one_channel_share_a_node_which_stops_with_the_last() -> None:
    """A second bus joins the node the first started; the node goes when both have left."""
    channel = _name("shared")
    first = can.Bus(interface="forcelearn-jr3", channel=channel)
    second = can.Bus(interface="forcelearn-jr3", channel=channel)
    assert first.node is second.node and first.node.hosts == 2
    first.shutdown()
    assert registry.lookup("jr3", channel) is second.node
    second.shutdown()
    assert registry.lookup("jr3", channel) is None


def test_a_bus_whose_node_stopped_fails_the_driver_with_a_bus_error() -> None:
    """The emulated adapter going away is a CAN error, which the driver reports as such."""
    channel = _name("gone")
    node = Jr3EmulatorNode(CellPhysics(), channel=channel, in_process=True)
    with can.Bus(interface="forcelearn-jr3", channel=channel) as bus:
        sensor = Jr3CanSensor(bus, Jr3Config(zero_settle_s=0.0, ack_timeout_s=0.2))
        sensor.initialise()
        node.close()
        with pytest.raises(SensorBusError, match="could not send"):
            sensor.read()
        sensor.close()


def test_async_streaming_reaches_a_notifier() -> None:
    """In async mode the node streams on the host's clock to the driver's Notifier thread."""
    with can.Bus(interface="forcelearn-jr3", channel=_name("async")) as bus, \
            Jr3CanSensor(bus, Jr3Config(mode="async", period_us=2000, zero_settle_s=0.0,
                                        stale_timeout_s=0.5)) as sensor:
        counters = [sensor.read().counter for _ in range(5)]
    assert counters == sorted(set(counters))


@pytest.mark.parametrize(
    ("options", "words"),
    [({}, "name a channel"), ({"channel": "x", "noise_std": [1.0]}, "6 values"),
     ({"channel": "x", "node_id": 300}, "1..127")],
)
def test_bad_bus_options_are_refused(options: dict[str, object], words: str) -> None:
    """Wrong options are a CanInitializationError naming the option."""
    with pytest.raises(can.CanInitializationError, match=words):
        can.Bus(interface="forcelearn-jr3", **options)
