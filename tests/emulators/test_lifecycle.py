"""Every emulator has one lifecycle: start (idempotent) -> close (idempotent), one address name."""

from __future__ import annotations

import gc
import itertools
import os
import time
import warnings
from collections.abc import Callable

import pytest

from forcelearn.emulators.computer_link import ComputerLinkEmulator
from forcelearn.emulators.egm import EgmControllerEmulator
from forcelearn.emulators.jr3 import Jr3EmulatorNode
from forcelearn.emulators.lifecycle import Emulator
from forcelearn.emulators.netft.server import NetFtEmulator
from forcelearn.emulators.physics.cell import CellPhysics
from forcelearn.emulators.pty_endpoint import PtyEndpoint
from forcelearn.emulators.slcan import SlcanAdapterEmulator

_numbers = itertools.count()


def _channel() -> str:
    return f"life-{os.getpid()}-{next(_numbers)}"


MAKERS: dict[str, Callable[[], Emulator]] = {
    "robot-pty": lambda: ComputerLinkEmulator("pty"),
    "robot-tcp": lambda: ComputerLinkEmulator("tcp"),
    "robot-inproc": lambda: ComputerLinkEmulator("inproc"),
    "jr3-virtual": lambda: Jr3EmulatorNode(CellPhysics(), channel=_channel()),
    "jr3-inproc": lambda: Jr3EmulatorNode(CellPhysics(), channel=_channel(), in_process=True),
    "slcan": lambda: SlcanAdapterEmulator(channel=_channel()),
    "egm": lambda: EgmControllerEmulator(0),
    "netft": lambda: NetFtEmulator(CellPhysics(), rdt_port=0, tcp_port=0),
}


@pytest.fixture(params=sorted(MAKERS))
def make(request: pytest.FixtureRequest) -> Callable[[], Emulator]:
    """A factory of one kind of emulator."""
    return MAKERS[request.param]


def test_start_is_idempotent_and_returns_the_address(make: Callable[[], Emulator]) -> None:
    """A second start changes nothing; both return the one address a client opens."""
    with make() as emulator:
        address = emulator.address
        assert address and emulator.start() == address == emulator.start()


def test_close_is_idempotent_and_final(make: Callable[[], Emulator]) -> None:
    """Close twice is fine; a closed emulator cannot serve again."""
    emulator = make()
    emulator.start()
    emulator.close()
    emulator.close()
    assert emulator.closed
    with pytest.raises(RuntimeError, match="closed"):
        emulator.start()


def test_an_emulator_collected_while_serving_warns_and_closes(
    make: Callable[[], Emulator],
) -> None:
    """Like an unclosed file: a ResourceWarning, and its threads and ports are released."""
    emulator = make()
    emulator.start()
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        emulator.__del__()
    assert any(issubclass(w.category, ResourceWarning) for w in caught)
    assert emulator.closed
    del emulator
    gc.collect()


def test_a_closed_emulator_does_not_warn(make: Callable[[], Emulator]) -> None:
    """Closed properly: nothing to say."""
    emulator = make()
    emulator.start()
    emulator.close()
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        emulator.__del__()
    assert not caught


def test_a_full_pty_drops_whole_writes_without_blocking() -> None:
    """A client that never reads: writes go on returning at once, drops are counted."""
    endpoint = PtyEndpoint("full")
    try:
        client = os.open(endpoint.address, os.O_RDWR | os.O_NOCTTY)
        try:
            chunk = b"x" * 1024
            t0 = time.monotonic()
            results = [endpoint.write(chunk) for _ in range(2000)]  # far more than a pty holds
            assert time.monotonic() - t0 < 2.0
            assert not all(results) and endpoint.dropped_writes == results.count(False)
            received = b""
            while len(received) < 64:  # what went out is whole chunks, never a cut one
                received += os.read(client, 65536)
            assert set(received) == {ord("x")}
        finally:
            os.close(client)
    finally:
        endpoint.close()
