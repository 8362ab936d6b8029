"""Fixtures: an emulated JR3 node and a driver on a private CAN channel per test.

Each test runs on both routes: python-can's ``virtual`` bus with the node's
thread behind it, and the in-process ``forcelearn-jr3`` interface.
"""

from __future__ import annotations

import itertools
import os
from collections.abc import Callable, Iterator
from typing import Any

import can
import pytest

from forcelearn.drivers.jr3_can.config import Jr3Config
from forcelearn.drivers.jr3_can.driver import Jr3CanSensor
from forcelearn.emulators.jr3 import Jr3EmulatorNode
from forcelearn.emulators.physics.cell import CellPhysics

_numbers = itertools.count()


@pytest.fixture
def channel(request: pytest.FixtureRequest) -> str:
    """A virtual CAN channel name no other test uses."""
    return f"jr3-{os.getpid()}-{next(_numbers)}-{request.node.name}"


@pytest.fixture(params=("virtual", "forcelearn-jr3"))
def route(request: pytest.FixtureRequest) -> str:
    """The python-can interface the host opens."""
    return request.param


@pytest.fixture
def physics() -> CellPhysics:
    """Free-space cell with a point tool (override in tests that need contact)."""
    return CellPhysics()


@pytest.fixture
def make_node(
    channel: str, physics: CellPhysics, route: str
) -> Iterator[Callable[..., Jr3EmulatorNode]]:
    """Factory of emulator nodes on the test's channel; all closed (threads joined) at teardown."""
    nodes: list[Jr3EmulatorNode] = []

    def make(**kwargs: Any) -> Jr3EmulatorNode:
        kwargs.setdefault("physics", physics)
        if route == "forcelearn-jr3" and "bus" not in kwargs:
            kwargs["in_process"] = True
        node = Jr3EmulatorNode(kwargs.pop("physics"), channel=channel, **kwargs)
        nodes.append(node)
        return node

    yield make
    for node in nodes:
        node.close()


@pytest.fixture
def bus(channel: str, route: str) -> Iterator[can.BusABC]:
    """The host's end of the test's channel."""
    with can.Bus(interface=route, channel=channel) as host_bus:
        yield host_bus


@pytest.fixture
def make_sensor(bus: can.BusABC) -> Iterator[Callable[..., Jr3CanSensor]]:
    """Factory of drivers on the host bus (short timeouts); all closed at teardown."""
    sensors: list[Jr3CanSensor] = []

    def make(on_sample: Any = None, **config: Any) -> Jr3CanSensor:
        config.setdefault("ack_timeout_s", 0.2)
        # a SYNC is waited for a quarter of this (0.1 s): long enough that a loaded host's
        # thread hand-over on the virtual route is not taken for a lost answer
        config.setdefault("stale_timeout_s", 0.4)
        config.setdefault("zero_settle_s", 0.0)
        # these tests compare readings with the true wrench (+ the model's bias): no zeroing
        # unless a test asks (the driver's default zeroes: test_default_config_zeroes...)
        config.setdefault("zero_on_init", False)
        sensor = Jr3CanSensor(bus, Jr3Config(**config), on_sample=on_sample)
        sensors.append(sensor)
        return sensor

    yield make
    for sensor in sensors:
        sensor.close()
