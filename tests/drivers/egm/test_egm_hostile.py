"""The EGM driver on a hostile network, over real loopback UDP (real mode, a thread).

A scripted controller socket plays the robot; a second socket plays a host on
the cell network. One test per way a hostile review found to break it.
"""

from __future__ import annotations

import math
import random
import socket
from collections.abc import Callable, Iterator
from contextlib import closing

import numpy as np
import pytest

from forcelearn.devices import Pose
from forcelearn.drivers.egm import EgmConfig, EgmRobot
from forcelearn.errors import ConfigError, InvalidTarget, LinkError, SafetyStop
from forcelearn.protocols.egm import codec

DOWN = (0.0, 1.0, 0.0, 0.0)
HOME = Pose(900.0, 0.0, 600.0, DOWN)
RAMP_MM = 100.0 * 0.004
"""One reply's largest planned-pose step at the default speed_mm_s and sample period."""
REPLY_WAIT_S = 0.5


def datagram(seqno: int, pose: Pose | None = HOME, version: codec.Version = "rw7",
             tm_ms: int | None = None, force: bool = False) -> bytes:
    """An EgmRobot of cycle ``seqno`` (4 ms cycles), guidance running."""
    return codec.encode_robot(codec.RobotMessage(
        seqno=seqno, tm_ms=4 * seqno if tm_ms is None else tm_ms, feedback=pose, planned=pose,
        time_us=4000 * seqno, motor=codec.MotorState.ON, mci=codec.MciState.RUNNING,
        rapid=codec.RapidState.RUNNING, measured_force=(0.0,) * 6 if force else None,
        fc_active=False if force else None,
    ), version)


class Peer:
    """A UDP socket on loopback that sends to the driver and reads its answers."""

    def __init__(self, driver_port: int) -> None:
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.sock.bind(("127.0.0.1", 0))
        self.address = ("127.0.0.1", driver_port)

    def send(self, data: bytes) -> None:
        """Send one datagram to the driver."""
        self.sock.sendto(data, self.address)

    def answer(self, timeout_s: float = REPLY_WAIT_S) -> codec.SensorMessage | None:
        """The next EgmSensor the driver sent here, or None if none came in ``timeout_s``."""
        self.sock.settimeout(timeout_s)
        try:
            data, _ = self.sock.recvfrom(65535)
        except TimeoutError:
            return None
        return codec.decode_sensor(data, "rw7")


class Controller(Peer):
    """The robot: sends cycle after cycle, its feedback the pose the driver last planned."""

    def __init__(self, driver_port: int) -> None:
        super().__init__(driver_port)
        self.seqno = -1
        self.pose = HOME
        self.planned: list[Pose] = []

    def cycle(self, pose: Pose | None = None, tm_offset_ms: int = 0) -> codec.SensorMessage | None:
        """Send the next cycle; return the answer (its planned pose becomes the feedback)."""
        self.seqno += 1
        self.send(datagram(self.seqno, pose or self.pose, tm_ms=4 * self.seqno + tm_offset_ms))
        reply = self.answer()
        if reply is not None and reply.planned is not None:
            self.planned.append(reply.planned)
            self.pose = reply.planned
        return reply


Cell = tuple[EgmRobot, "Controller", "Peer"]


@pytest.fixture
def cell() -> Iterator[tuple[EgmRobot, Controller, Peer]]:
    """A real-mode driver with a session open to the controller, and a host on the network."""
    robot = EgmRobot(EgmConfig(port=0, lockstep=False, watchdog_s=1.0, stale_after_s=1.0))
    controller, intruder = Controller(robot.port), Peer(robot.port)
    try:
        assert controller.cycle() is not None
        robot.wait_for_session(2.0)
        yield robot, controller, intruder
    finally:
        robot.close()
        controller.sock.close()
        intruder.sock.close()


def assert_ramped(planned: list[Pose]) -> None:
    """Every planned pose inside the default workspace, each within one ramp step of the last."""
    for pose in planned:
        assert 300.0 <= pose.x_mm <= 1500.0 and math.isfinite(pose.z_mm)
    steps = np.linalg.norm(np.diff([p.position_mm for p in planned], axis=0), axis=1)
    assert np.all(steps <= RAMP_MM + 1e-9), steps.max()


def test_a_spoofed_session_start_from_another_port_is_never_answered_nor_used(cell: Cell) -> None:
    """Seqno 0 with x = 2500 mm from another port: not answered, no new session, no jump."""
    robot, controller, intruder = cell
    for _ in range(3):
        controller.cycle()
    intruder.send(datagram(0, Pose(2500.0, 0.0, 600.0, DOWN), tm_ms=10_000))
    assert controller.cycle() is not None
    assert intruder.answer(0.1) is None
    assert robot.stats.sessions == 1 and robot.stats.foreign_datagrams == 1
    assert robot.read_pose() == controller.pose
    assert_ramped(controller.planned)


def test_a_replayed_session_start_does_not_move_the_plan_beyond_the_ramp(cell: Cell) -> None:
    """The controller's own seqno-0 datagram replayed from its address after a 3 mm move."""
    robot, controller, _ = cell
    first = datagram(0, HOME)
    robot.move_by(dz_mm=-3.0)
    for _ in range(12):
        controller.cycle()
    assert controller.pose.z_mm < 597.5
    controller.send(first)  # what a host that captured the start would send
    controller.cycle()
    controller.cycle()
    assert_ramped(controller.planned)
    assert robot.stats.replays == 1 and robot.stats.sessions == 1
    assert robot.target is not None and robot.target.z_mm == pytest.approx(597.0)


def test_a_forged_restart_from_the_controllers_address_does_not_cut_off_its_stream(
    cell: Cell,
) -> None:
    """A seqno 0 (newer tm, 3 mm away) forged from the controller's address: its stream goes on."""
    robot, controller, _ = cell
    for _ in range(300):  # more than one watchdog of cycles: seqno 301 is no plausible jump from 0
        assert controller.cycle() is not None
    controller.send(datagram(0, HOME.moved(dz_mm=-3.0), tm_ms=10**6))
    assert controller.answer() is not None  # indistinguishable from a restart, but ramped
    for _ in range(3):
        assert controller.cycle() is not None
    assert_ramped(controller.planned)
    assert robot.stats.resumed_streams == 1


def test_a_replayed_datagram_of_an_earlier_session_is_ignored(cell: Cell) -> None:
    """Found by the fuzz: an old session's datagram whose seqno is ahead of the new session's."""
    robot, controller, _ = cell
    for _ in range(20):
        controller.cycle()
    captured = datagram(15, controller.pose, tm_ms=4 * 15)
    controller.seqno = -1
    controller.send(datagram(0, controller.pose, tm_ms=1000))  # a real restart, later
    assert controller.answer() is not None
    controller.seqno = 0
    for _ in range(5):
        controller.cycle(tm_offset_ms=1000)
    controller.send(captured)  # seqno 15 > 5, within the bound, but its tm is older
    assert controller.answer(0.2) is None
    reply = controller.cycle(tm_offset_ms=1000)
    assert reply is not None and reply.tm_ms == 4 * 6 + 1000
    assert robot.stats.replays == 1 and robot.stats.sessions == 2
    assert_ramped(controller.planned)


def test_a_forged_far_future_tm_holds_the_stream_back_only_a_few_cycles(cell: Cell) -> None:
    """Found by the fuzz: the next seqno with tm + 2^31 - 10 from the controller's address."""
    robot, controller, _ = cell
    controller.cycle()
    far_tm = 4 * controller.seqno + 2**31 - 10
    forged = datagram(controller.seqno + 1, controller.pose, tm_ms=far_tm)
    controller.send(forged)
    assert controller.answer() is not None  # a plausible forgery: taken, and answered
    answered = []
    for _ in range(8):  # each real cycle now looks older than the forgery
        controller.seqno += 1
        controller.send(datagram(controller.seqno, controller.pose))
        answered.append(controller.answer(0.05) is not None)
    assert answered[:2] == [False, False] and all(answered[4:])
    assert robot.stats.resyncs == 1


def test_a_foreign_next_seqno_datagram_is_not_taken_as_feedback(cell: Cell) -> None:
    """Another host's datagram with the controller's next seqno: ignored, feedback unchanged."""
    robot, controller, intruder = cell
    controller.cycle()
    intruder.send(datagram(controller.seqno + 1, HOME.moved(dx_mm=5.0)))
    assert intruder.answer(0.2) is None
    assert robot.read_pose() == controller.pose
    assert robot.stats.foreign_datagrams == 1
    assert controller.cycle() is not None  # the controller's own next cycle is still fresh


def _random_64k() -> bytes:
    return random.Random(27).randbytes(65507)  # the largest IPv4 UDP payload


MALFORMED: dict[str, Callable[[], bytes]] = {
    "one byte 0b": lambda: b"\x0b",
    "7-byte truncation": lambda: datagram(5)[:7],
    "64 kB random": _random_64k,
    "RW6 datagram to an RW7 driver": lambda: datagram(5, version="rw6", force=True),
}


@pytest.mark.parametrize("name", list(MALFORMED))
def test_a_malformed_datagram_from_the_controllers_address_does_not_end_the_session(
    cell: Cell, name: str
) -> None:
    """Each datagram of the review, from the controller's own address: counted and ignored."""
    robot, controller, _ = cell
    controller.send(MALFORMED[name]())
    assert controller.cycle() is not None
    assert controller.cycle() is not None
    robot.move_by(dz_mm=-1.0)  # the session goes on: the robot still takes targets
    stats = robot.stats
    assert stats.bad_datagrams + stats.wrong_version == 1
    assert stats.sessions == 1


@pytest.mark.parametrize("sender", ["intruder", "controller"])
def test_a_huge_seqno_jump_does_not_silence_the_real_controller(cell: Cell, sender: str) -> None:
    """Seqno + 2^31 - 2, from another host or spoofing the controller: ignored, stream goes on."""
    robot, controller, intruder = cell
    controller.cycle()
    peer = intruder if sender == "intruder" else controller
    peer.send(datagram((controller.seqno + 2**31 - 2) % 2**32))
    for _ in range(3):
        assert controller.cycle() is not None
    stats = robot.stats
    assert stats.out_of_order == 0 and stats.foreign_datagrams + stats.seqno_jumps == 1


def test_a_three_element_quaternion_is_refused_where_it_is_passed(cell: Cell) -> None:
    """move_to with (0, 1, 0): InvalidTarget at the call; the receive thread lives on."""
    robot, controller, _ = cell
    with pytest.raises(InvalidTarget, match="4 numbers"):
        robot.move_to(Pose(900.0, 0.0, 599.0, (0.0, 1.0, 0.0)))  # type: ignore[arg-type]
    for bad in (Pose(math.nan, 0.0, 600.0, DOWN), Pose(2500.0, 0.0, 600.0, DOWN), "home"):
        with pytest.raises(InvalidTarget):
            robot.move_to(bad)  # type: ignore[arg-type]
    assert controller.cycle() is not None
    assert robot.read_pose() == controller.pose


def test_a_session_starting_from_nan_feedback_is_refused_and_never_sends_nan() -> None:
    """Seqno 0 with x = NaN: no answer, SafetyStop at the wait; a sound cycle then starts it."""
    with closing(EgmRobot(EgmConfig(port=0, lockstep=False, stale_after_s=1.0))) as robot:
        controller = Controller(robot.port)
        try:
            controller.send(datagram(0, Pose(math.nan, 0.0, 600.0, DOWN)))
            assert controller.answer(0.2) is None
            with pytest.raises(SafetyStop, match="finite"):
                robot.wait_for_session(0.2)
            assert robot.stats.refused_sessions == 1
            controller.seqno = 0
            reply = controller.cycle()
            assert reply is not None and reply.planned == HOME
            assert robot.wait_for_session(1.0) == HOME
        finally:
            controller.sock.close()


def test_a_session_outside_the_workspace_is_refused() -> None:
    """Feedback x = 2500 mm at the start: refused with SafetyStop, nothing answered."""
    with closing(EgmRobot(EgmConfig(port=0, lockstep=False))) as robot:
        controller = Controller(robot.port)
        try:
            controller.send(datagram(0, Pose(2500.0, 0.0, 600.0, DOWN)))
            assert controller.answer(0.2) is None
            with pytest.raises(SafetyStop, match="workspace"):
                robot.wait_for_session(0.1)
        finally:
            controller.sock.close()


def test_a_dead_receive_thread_is_reported_as_the_reason(cell: Cell) -> None:
    """If the thread ever ends, the next call says so (LinkError), not a stale-feedback timeout."""
    robot, controller, _ = cell

    def broken() -> bytes:
        raise RuntimeError("broken reply")

    robot._guidance.reply = broken  # type: ignore[method-assign]
    controller.cycle()
    with pytest.raises(LinkError, match="receive thread ended") as info:
        robot.read_pose()
    assert "stale" not in str(info.value)


def test_a_configured_controller_address_and_port_exclude_every_other_sender() -> None:
    """controller_host/port set: a datagram from 127.0.0.1 on another port is foreign."""
    probe = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    probe.bind(("127.0.0.1", 0))
    port = probe.getsockname()[1]
    config = EgmConfig(port=0, lockstep=False, controller_host="127.0.0.1", controller_port=port)
    with closing(EgmRobot(config)) as robot:
        other = Peer(robot.port)
        try:
            other.send(datagram(0))
            assert other.answer(0.2) is None
            probe.sendto(datagram(0), ("127.0.0.1", robot.port))
            robot.wait_for_session(1.0)
            assert robot.stats.foreign_datagrams == 1 and robot.stats.sessions == 1
        finally:
            other.sock.close()
            probe.close()


@pytest.mark.parametrize(
    ("table", "key"),
    [
        ({"controller_host": "robot.local"}, "controller_host"),
        ({"controller_host": "300.1.1.1"}, "controller_host"),
        ({"controller_host": 3232235777}, "controller_host"),
        ({"controller_host": "192.168.125.1", "controller_port": 0}, "controller_port"),
        ({"controller_host": "192.168.125.1", "controller_port": True}, "controller_port"),
        ({"controller_port": 6510}, "controller_port"),
    ],
)
def test_bad_controller_address_keys_are_config_errors(table: dict[str, object], key: str) -> None:
    """Controller address keys are checked at load and named."""
    with pytest.raises(ConfigError, match=rf"robot\.{key} (must|needs)"):
        EgmConfig(port=0, **table)  # type: ignore[arg-type]
