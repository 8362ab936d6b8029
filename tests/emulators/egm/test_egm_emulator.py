"""The EGM controller emulator at the wire, driven by a bare UDP peer (no driver)."""

from __future__ import annotations

import math
import socket
import subprocess
import sys
from collections.abc import Iterator
from contextlib import closing

import pytest

from forcelearn.devices import Pose
from forcelearn.drivers.egm import EgmConfig, EgmRobot
from forcelearn.emulators.clock import SimClock
from forcelearn.emulators.egm import (
    EgmControllerConfig,
    EgmControllerEmulator,
    EgmFaultConfig,
    Fault,
    LagServo,
    ServoParams,
)
from forcelearn.emulators.egm import server as egm_server
from forcelearn.emulators.physics.cell import CellPhysics
from forcelearn.protocols.egm import codec

HOME = Pose(900.0, 0.0, 600.0, (0.0, 1.0, 0.0, 0.0))


class Peer:
    """A minimal PC side: receives EgmRobot, answers with a chosen planned pose."""

    def __init__(self) -> None:
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.sock.bind(("127.0.0.1", 0))
        self.sock.settimeout(5.0)
        self.seqno = 0

    @property
    def port(self) -> int:
        """The bound port (the emulator's remote port)."""
        return self.sock.getsockname()[1]

    def receive(self) -> tuple[codec.RobotMessage, tuple[str, int]]:
        """Next EgmRobot (RW7) and its sender."""
        data, address = self.sock.recvfrom(65535)
        return codec.decode_robot(data, "rw7"), address

    def answer(self, address: tuple[str, int], planned: Pose) -> None:
        """Send one EgmSensor."""
        message = codec.SensorMessage(self.seqno, 0, planned)
        self.seqno += 1
        self.sock.sendto(codec.encode_sensor(message, "rw7"), address)


@pytest.fixture
def peer() -> Iterator[Peer]:
    """A bare PC side on loopback."""
    p = Peer()
    yield p
    p.sock.close()


def sim_s(message: codec.RobotMessage) -> float:
    """Simulated time of an EgmRobot: its feedBack.time less the default clock epoch, s."""
    assert message.time_us is not None
    return (message.time_us - EgmControllerConfig().clock_epoch_us) / 1e6


def run(peer: Peer, emulator: EgmControllerEmulator, cycles: int,
        plan: dict[int, Pose] | None = None) -> list[codec.RobotMessage]:
    """Answer ``cycles`` fresh messages (the pose of ``plan`` from that count on)."""
    seen: list[codec.RobotMessage] = []
    planned, last = HOME, -1
    with emulator:
        while len(seen) < cycles:
            message, address = peer.receive()
            seen.append(message)
            fresh = message.seqno > last or (message.seqno == 0 and last != 0)
            if not fresh:
                continue
            last = message.seqno
            planned = (plan or {}).get(len(seen) - 1, planned)
            peer.answer(address, planned)
    return seen


def emulator_for(peer: Peer, **kw: object) -> EgmControllerEmulator:
    """A lockstep emulator sending to ``peer``."""
    kw.setdefault("physics", CellPhysics(pose=HOME))
    return EgmControllerEmulator(peer.port, **kw)  # type: ignore[arg-type]


def test_session_starts_at_seqno_zero_on_the_simulated_sample_clock(peer: Peer) -> None:
    """Seqno 0, 1, 2...; feedBack.time and tm step by exactly 4 ms of simulated time."""
    seen = run(peer, emulator_for(peer), 6)
    assert [m.seqno for m in seen] == list(range(6))
    epoch = EgmControllerConfig().clock_epoch_us
    assert [m.time_us for m in seen] == [epoch + 4000 * k for k in range(6)]
    assert [m.tm_ms for m in seen] == [0, 4, 8, 12, 16, 20]
    assert all(m.mci is codec.MciState.RUNNING and m.motor is codec.MotorState.ON for m in seen)


def test_answers_are_read_next_cycle_and_act_after_the_control_lag(peer: Peer) -> None:
    """A planned pose answered at cycle 0 is read at 4 ms and moves nothing before 24 ms."""
    target = HOME.moved(dz_mm=-1.0)
    seen = run(peer, emulator_for(peer), 12, plan={0: target})
    assert seen[1].planned == target
    assert all(m.feedback == HOME for m in seen if sim_s(m) <= 0.024 + 1e-9)
    assert seen[11].feedback.z_mm < 600.0


def test_next_cycle_after_another_device_moved_the_clock(peer: Peer) -> None:
    """If the clock ran past the next sample instant, the cycle moves to the one after it."""
    clock = SimClock()
    with emulator_for(peer, clock=clock):
        first, address = peer.receive()
        clock.advance_to(0.010)  # e.g. a sensor exchange while the controller waited
        peer.answer(address, HOME)
        second, _ = peer.receive()
    assert (sim_s(first), sim_s(second)) == (0.0, pytest.approx(0.012))


@pytest.mark.parametrize(
    ("fault", "seqnos"),
    [
        ("lose", [0, 1, 2, 4, 5, 6]),
        ("duplicate", [0, 1, 2, 3, 3, 4]),
        ("reorder", [0, 1, 2, 4, 3, 5]),
        ("restart", [0, 1, 2, 0, 1, 2]),
    ],
)
def test_controller_datagram_faults_on_the_wire(peer: Peer, fault: str, seqnos: list[int]) -> None:
    """Lost, duplicated, reordered datagrams and a restart, exactly at cycle 3."""
    faults = EgmFaultConfig(**{fault: Fault(1.0, limit=1)}, after_cycles=3)
    seen = run(peer, emulator_for(peer, faults=faults), len(seqnos))
    assert [m.seqno for m in seen] == seqnos


def test_lost_and_late_answers_keep_the_last_planned_pose(
    peer: Peer, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A lost answer is never read; a late one is read one cycle late (the last one meanwhile).

    Each run has a PC side of its own: a datagram the first emulator sent just
    before it stopped would otherwise be the second run's first message (seen on
    a loaded host). Lockstep resends a waiting cycle after RESEND_S of wall time;
    a slow peer on a loaded host is not what is tested here either.
    """
    monkeypatch.setattr(egm_server, "RESEND_S", 30.0)
    plan = {k: HOME.moved(dz_mm=-0.1 * k) for k in range(10)}
    lost = run(peer, emulator_for(peer, faults=EgmFaultConfig(
        lose_reply=Fault(1.0, limit=1), after_cycles=3)), 8, plan)
    second = Peer()
    try:
        late = run(second, emulator_for(second, faults=EgmFaultConfig(
            late_reply=Fault(1.0, limit=1), after_cycles=3)), 8, plan)
    finally:
        second.sock.close()
    z = [round(m.planned.z_mm, 3) for m in lost]
    # answer k is read at cycle k+1; the answer to cycle 3 is lost
    assert z[3:7] == [599.8, 599.8, 599.6, 599.5]
    z = [round(m.planned.z_mm, 3) for m in late]
    # the answer to cycle 3 is read at cycle 5 together with the answer to cycle 4 (newer wins)
    assert z[3:7] == [599.8, 599.8, 599.6, 599.5]


def test_comm_timeout_stops_guidance_and_reports_it(peer: Peer) -> None:
    """A silent PC: after CommTimeout the controller reports MCI_STOPPED and RAPID_STOPPED."""
    config = EgmControllerConfig(comm_timeout_s=0.02)
    emulator = emulator_for(peer, config=config, patience_s=0.01)
    with emulator:
        for _ in range(3):
            message, address = peer.receive()
            peer.answer(address, HOME)
        assert emulator.guidance_stopped.wait(5.0)
        while message.mci is codec.MciState.RUNNING:
            message, _ = peer.receive()
    assert message.mci is codec.MciState.STOPPED and message.rapid is codec.RapidState.STOPPED
    # the answer to cycle 2 is read at cycle 3 (12 ms); 20 ms later guidance ends
    assert sim_s(message) == pytest.approx(0.012 + 0.020, abs=1e-9)


def test_a_planned_pose_outside_the_workspace_is_a_motion_error(peer: Peer) -> None:
    """The controller refuses it: MCI_ERROR, the robot holds."""
    seen = run(peer, emulator_for(peer), 4, plan={0: Pose(100.0, 0.0, 600.0, HOME.quaternion)})
    assert seen[1].mci is codec.MciState.ERROR and seen[3].feedback == HOME


def test_lag_servo_dead_time_then_first_order() -> None:
    """No motion before the control lag, then 1 - exp(-t/tau) of the step."""
    servo = LagServo(ServoParams(control_lag_s=0.02, time_constant_s=0.01), HOME, 0.0)
    servo.command(HOME.moved(dz_mm=-10.0), 0.0)
    assert servo.advance_to(0.02) == HOME
    z = servo.advance_to(0.03).z_mm
    assert 600.0 - z == pytest.approx(10.0 * (1 - math.exp(-1.0)))


def test_two_processes_driver_and_emulator(tmp_path: object) -> None:
    """The emulator in its own process (python -m ... prints its port) guides the real driver."""
    with closing(EgmRobot(EgmConfig(port=0, lockstep=True, watchdog_s=10.0))) as robot:
        process = subprocess.Popen(
            [sys.executable, "-m", "forcelearn.emulators.egm", "--remote-port", str(robot.port)],
            stdout=subprocess.PIPE, text=True,
        )
        try:
            line = process.stdout.readline()  # type: ignore[union-attr]
            assert line.startswith("EGM ") and int(line.split()[1]) > 0
            start = robot.wait_for_session(30.0)
            robot.move_by(dx_mm=2.0)
            robot.wait_in_position(timeout_s=1.0, settle_s=0.02)
            reached = robot.read_pose()
            assert abs(reached.x_mm - start.x_mm - 2.0) <= robot.config.in_position_mm
        finally:
            process.terminate()
            process.wait(timeout=30)
    assert process.returncode == 0
