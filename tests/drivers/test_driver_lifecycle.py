"""Every driver has one lifecycle: open (idempotent, also on entering ``with``) -> close (final).

The same tests run against the four drivers, each against its emulator
(forcelearn.drivers.lifecycle). A case builds a driver that is not yet opened,
a driver whose device never answers, and, where the emulator shows it, a
probe that the device was brought to rest by ``close``.
"""

from __future__ import annotations

import gc
import itertools
import math
import os
import subprocess
import sys
import time
import warnings
import weakref
from collections.abc import Callable, Iterator
from contextlib import ExitStack
from dataclasses import dataclass
from typing import Any

import can
import pytest

from forcelearn.devices import Pose
from forcelearn.drivers.computer_link import ComputerLinkRobot, LinkConfig
from forcelearn.drivers.egm import EgmConfig, EgmRobot
from forcelearn.drivers.jr3_can.config import Jr3Config
from forcelearn.drivers.jr3_can.driver import Jr3CanSensor
from forcelearn.drivers.lifecycle import Driver
from forcelearn.drivers.netft import NetFtConfig, NetFtSensor
from forcelearn.emulators.clock import SimClock
from forcelearn.emulators.computer_link import ComputerLinkEmulator
from forcelearn.emulators.egm import EgmControllerEmulator, InProcessEgmController
from forcelearn.emulators.jr3 import Jr3EmulatorNode
from forcelearn.emulators.netft.server import NetFtEmulator
from forcelearn.emulators.physics.cell import CellPhysics
from forcelearn.errors import ForcelearnError
from forcelearn.protocols.egm import codec

HOME = Pose(900.0, 0.0, 600.0, (0.0, 1.0, 0.0, 0.0))
_numbers = itertools.count()


@dataclass
class Case:
    """One driver kind against its emulator; ``stack`` closes the emulators after the test."""

    make: Callable[[], Driver]
    """A driver, constructed, not yet opened."""
    make_silent: Callable[[], Driver]
    """A driver whose device never answers (construction itself may fail)."""
    use: Callable[[Any], object]
    """One ordinary call (a read)."""
    traffic: Callable[[], int]
    """What the emulator has received so far (requests, commands, bytes)."""
    ready_at_construction: bool | None = False
    """None: the controller may start the session before the driver is opened."""
    busy: Callable[[Any], None] | None = None
    """Set the device going (a move, a stream) and check that it goes, before it is closed."""
    at_rest: Callable[[], bool] | None = None
    """True once the device was told to stop (robot braked or held, stream stopped)."""


def _computer_link(stack: ExitStack) -> Case:
    emulator = stack.enter_context(ComputerLinkEmulator("inproc"))
    fast = {"ack_timeout_s": 0.05, "reply_timeout_s": 0.05}
    commanded: list[float] = []
    gone = ComputerLinkEmulator("inproc")
    gone.start()
    gone.close()

    def busy(robot: ComputerLinkRobot) -> None:
        robot.move_by(dz_mm=-8.0)  # the arm takes far longer than the close that follows
        commanded.append(robot.read_target().z_mm)
        assert not at_rest()

    def at_rest() -> bool:  # braked: the controller's target is no longer the commanded one
        return abs(emulator.engine.motion.target.z_mm - commanded[-1]) > 1.0

    return Case(
        make=lambda: ComputerLinkRobot(LinkConfig(url=emulator.address, **fast)),
        make_silent=lambda: ComputerLinkRobot(LinkConfig(url=gone.address, **fast)),
        use=lambda robot: robot.read_pose(),
        traffic=lambda: emulator.bytes_received,
        ready_at_construction=True,
        busy=busy,
        at_rest=at_rest,
    )


class RecordingSocket:
    """The in-process controller's socket, keeping every EgmSensor the driver sent."""

    def __init__(self, inner: Any) -> None:
        self.inner = inner
        self.sent: list[bytes] = []

    def sendto(self, data: bytes, address: Any, /) -> int:  # noqa: D102
        self.sent.append(bytes(data))
        return int(self.inner.sendto(data, address))

    def __getattr__(self, name: str) -> Any:
        return getattr(self.inner, name)


def _egm_lockstep(stack: ExitStack) -> Case:
    controller = InProcessEgmController(physics=CellPhysics(pose=HOME), clock=SimClock())
    stack.callback(controller.close)
    sockets: list[RecordingSocket] = []
    measured: list[Pose] = []

    def make() -> EgmRobot:
        sockets.append(RecordingSocket(controller.socket()))
        return EgmRobot(EgmConfig(lockstep=True), sock=sockets[-1])

    def planned(index: int) -> Pose:
        message = codec.decode_sensor(sockets[-1].sent[index], "rw6")
        assert message.planned is not None
        return message.planned

    def busy(robot: EgmRobot) -> None:
        robot.move_by(dz_mm=-8.0)
        robot.dwell(0.05)  # the planned pose ramps down, the measured one lags behind it
        measured.append(robot.read_pose())
        assert not at_rest()

    def at_rest() -> bool:
        """The last answer turned the ramp back toward the measured pose: held, not going on."""
        if not measured or len(sockets[-1].sent) < 2:
            return False
        held = measured[-1].position_mm
        return bool(math.dist(planned(-1).position_mm, held)
                    < math.dist(planned(-2).position_mm, held))

    return Case(
        make=make,
        make_silent=lambda: EgmRobot(
            EgmConfig(port=0, lockstep=True, first_message_timeout_s=0.2)
        ),
        use=lambda robot: robot.read_pose(),
        traffic=lambda: controller.replies,
        busy=busy,
        at_rest=at_rest,
    )


def _egm_real(stack: ExitStack) -> Case:
    """Real mode: the receive thread answers; the controller runs at its own (real) pace."""
    config = EgmConfig(port=0, lockstep=False, watchdog_s=1.0, stale_after_s=1.0,
                       first_message_timeout_s=5.0)

    def make() -> EgmRobot:
        robot = EgmRobot(config)
        controller = EgmControllerEmulator(robot.port, clock=SimClock(time_scale=1.0),
                                           lockstep=False)
        stack.callback(controller.close)
        controller.start()
        return robot

    return Case(
        make=make,
        make_silent=lambda: EgmRobot(
            EgmConfig(port=0, lockstep=False, first_message_timeout_s=0.2)
        ),
        use=lambda robot: robot.read_pose(),
        traffic=lambda: 0,  # the controller sends on its own clock: nothing to count
        ready_at_construction=None,
    )


def _jr3(mode: str) -> Callable[[ExitStack], Case]:
    def case(stack: ExitStack) -> Case:
        channel = f"life-drv-{os.getpid()}-{next(_numbers)}"
        node = stack.enter_context(Jr3EmulatorNode(CellPhysics(), channel=channel,
                                                   in_process=True))
        config = Jr3Config(mode=mode, ack_timeout_s=0.2, stale_timeout_s=0.4, zero_settle_s=0.0)

        def make() -> Jr3CanSensor:
            bus = stack.enter_context(can.Bus(interface="forcelearn-jr3", channel=channel))
            return Jr3CanSensor(bus, config)

        return Case(
            make=make,
            make_silent=lambda: Jr3CanSensor(
                stack.enter_context(can.Bus(interface="virtual", channel=f"{channel}-nobody")),
                config,
            ),
            use=lambda sensor: sensor.read(),
            traffic=lambda: node.stats.commands,
            busy=lambda sensor: None if node.mode == mode else pytest.fail(node.mode),
            at_rest=lambda: node.mode == "idle",
        )

    return case


def _netft(stack: ExitStack) -> Case:
    emulator = stack.enter_context(
        NetFtEmulator(CellPhysics(), rdt_port=0, tcp_port=0, rdt_rate_hz=1000.0)
    )
    ports = emulator.ports
    config = NetFtConfig(host=emulator.host, mode="stream", stale_timeout_s=1.0, **ports)
    nobody = NetFtEmulator(CellPhysics(), rdt_port=0, tcp_port=0)
    silent_ports = nobody.ports
    nobody.close()
    handled: list[int] = []

    def busy(sensor: NetFtSensor) -> None:
        sensor.read()
        assert emulator.wait_handled(sensor.stats.requests) and emulator.streaming
        handled.append(sensor.stats.requests)

    def at_rest() -> bool:  # the STOP datagram reached the box and ended the stream
        return emulator.wait_handled(handled[-1] + 1) and not emulator.streaming

    return Case(
        make=lambda: NetFtSensor(config),
        make_silent=lambda: NetFtSensor(NetFtConfig(host=emulator.host, connect_timeout_s=0.2,
                                                    **silent_ports)),
        use=lambda sensor: sensor.read(),
        traffic=lambda: (emulator.stats.requests + emulator.stats.http_requests
                         + emulator.stats.calinfo_requests),
        busy=busy,
        at_rest=at_rest,
    )


CASES: dict[str, Callable[[ExitStack], Case]] = {
    "computer_link": _computer_link,
    "egm-lockstep": _egm_lockstep,
    "egm-real": _egm_real,
    "jr3-sync": _jr3("sync"),
    "jr3-async": _jr3("async"),
    "netft": _netft,
}


@pytest.fixture(params=sorted(CASES))
def case(request: pytest.FixtureRequest) -> Iterator[Case]:
    """One driver kind and its emulator, torn down after the test."""
    with ExitStack() as stack:
        yield CASES[request.param](stack)


def _collect(ref: weakref.ref[Driver]) -> None:
    """Collect until the driver is gone (a receive thread may hold it for one poll).

    Its weak reference is cleared after its ``__del__`` has run, wherever that ran.
    """
    deadline = time.monotonic() + 5.0
    while ref() is not None and time.monotonic() < deadline:
        gc.collect()
        time.sleep(0.01)
    assert ref() is None, "the driver was never collected"


def _resource_warnings(caught: list[warnings.WarningMessage]) -> list[str]:
    return [str(w.message) for w in caught if issubclass(w.category, ResourceWarning)]


def test_entering_with_makes_the_device_ready(case: Case) -> None:
    """Before: only the computer link is ready; inside: every driver is; after: closed."""
    driver = case.make()
    assert case.ready_at_construction in (None, driver.ready) and not driver.closed
    with driver as entered:
        assert entered is driver and driver.ready
        case.use(driver)
    assert driver.closed and not driver.ready


def test_open_is_idempotent(case: Case) -> None:
    """A second open (or a with after open) reaches the device no more."""
    with case.make() as driver:
        assert driver.open() is driver
        before = case.traffic()
        assert driver.open() is driver
        with driver:
            assert case.traffic() == before
        assert driver.closed


def test_close_is_idempotent_and_final(case: Case) -> None:
    """Close twice is fine; a closed driver refuses open() and calls with its typed error."""
    driver = case.make().open()
    driver.close()
    driver.close()
    assert driver.closed
    with pytest.raises(ForcelearnError, match="closed"):
        driver.open()
    with pytest.raises(ForcelearnError, match="closed"):
        case.use(driver)


def test_closing_brings_the_device_to_rest(case: Case) -> None:
    """A robot is stopped (braked or held), a sensor's stream is stopped."""
    if case.busy is None or case.at_rest is None:
        pytest.skip("this emulator shows no state to check it against")
    with case.make() as driver:
        case.busy(driver)
    assert case.at_rest()


def test_a_silent_device_fails_at_the_with_line_and_leaves_nothing_open(case: Case) -> None:
    """A typed error on entering, the driver closed (or never built), nothing to warn about."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        with pytest.raises(ForcelearnError), case.make_silent():  # construction is on it too
            pytest.fail("a silent device was opened")
        gc.collect()
    assert not _resource_warnings(caught)


def test_a_driver_collected_open_warns_and_is_closed(case: Case) -> None:
    """Like an unclosed file: a ResourceWarning, and the device is stopped."""
    driver = case.make().open()
    if case.busy is not None:
        case.busy(driver)
    ref = weakref.ref(driver)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        del driver
        _collect(ref)
    assert any("was not closed" in message for message in _resource_warnings(caught))
    if case.at_rest is not None:
        assert case.at_rest()


def test_a_closed_driver_does_not_warn(case: Case) -> None:
    """Closed properly: nothing to say when collected."""
    driver = case.make().open()
    driver.close()
    ref = weakref.ref(driver)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        del driver
        _collect(ref)
    assert not _resource_warnings(caught)


LEFT_OPEN_AT_EXIT = """
import can
from forcelearn.drivers.computer_link import ComputerLinkRobot, LinkConfig
from forcelearn.drivers.jr3_can.driver import Jr3CanSensor
from forcelearn.emulators.jr3 import Jr3EmulatorNode
from forcelearn.emulators.physics.cell import CellPhysics
from forcelearn.emulators.computer_link import ComputerLinkEmulator

emulator = ComputerLinkEmulator("inproc")
emulator.start()
robot = ComputerLinkRobot(LinkConfig(url=emulator.address))
node = Jr3EmulatorNode(CellPhysics(), channel="exit", in_process=True)
sensor = Jr3CanSensor(can.Bus(interface="forcelearn-jr3", channel="exit"))
sensor.initialise()
print("open")
"""
DRIVER_NAMES = ("ComputerLinkRobot", "Jr3CanSensor")


def test_drivers_left_open_are_quiet_at_interpreter_exit() -> None:
    """A program that ends with drivers open prints no warning on the way out."""
    result = subprocess.run(
        [sys.executable, "-W", "always::ResourceWarning", "-c", LEFT_OPEN_AT_EXIT],
        capture_output=True, text=True, timeout=60, check=False,
    )
    assert result.returncode == 0 and result.stdout == "open\n", result.stderr
    assert not [name for name in DRIVER_NAMES if name in result.stderr], result.stderr
