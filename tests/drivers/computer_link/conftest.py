"""Fixtures: an emulated controller on each transport and a driver factory with short timeouts."""

from __future__ import annotations

from collections.abc import Callable, Iterator
from contextlib import ExitStack

import pytest

from forcelearn.drivers.computer_link import ComputerLinkRobot, LinkConfig
from forcelearn.emulators.computer_link import ComputerLinkEmulator
from forcelearn.emulators.physics.arm import ArmConfig

TRANSPORTS = ("pty", "tcp", "inproc")

# Short timeouts keep fault tests quick; far above loopback round trips (< 1 ms).
FAST = {"ack_timeout_s": 0.05, "reply_timeout_s": 0.05}


@pytest.fixture(params=TRANSPORTS)
def transport(request: pytest.FixtureRequest) -> str:
    """Each driver test runs over a real pty, socket://127.0.0.1 and forcelearn-robot://."""
    return request.param


@pytest.fixture
def make_emulator(transport: str) -> Iterator[Callable[..., ComputerLinkEmulator]]:
    """Start emulators on the current transport; all are stopped at teardown.

    Protocol tests get an instant arm unless they pass a ``config`` (motion in
    time is tested with the realistic defaults where it matters).
    """
    with ExitStack() as stack:

        def make(**kwargs: object) -> ComputerLinkEmulator:
            kwargs.setdefault("config", ArmConfig(instant=True))
            return stack.enter_context(ComputerLinkEmulator(transport, **kwargs))

        yield make


@pytest.fixture
def emulator(make_emulator: Callable[..., ComputerLinkEmulator]) -> ComputerLinkEmulator:
    """A fault-free emulated controller."""
    return make_emulator()


@pytest.fixture
def connect() -> Iterator[Callable[..., ComputerLinkRobot]]:
    """Open drivers with fast timeouts; all are closed at teardown."""
    with ExitStack() as stack:

        def open_robot(url: str, **kwargs: object) -> ComputerLinkRobot:
            return stack.enter_context(ComputerLinkRobot(LinkConfig(url=url, **(FAST | kwargs))))

        yield open_robot
