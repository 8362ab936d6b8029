"""The emulated EGM controller against ABB's manual, read and written on the wire (egm_wire).

Every expectation comes from a document, cited at the test: ABB's application
manual *Externally Guided Motion* RW7 (3HAC073318-001 rev K, "manual"), and
for the emulated arm's axis ranges and servo time constant the fidelity table
in docs/emulators.md ("### EGM"). The emulator is only the device under test:
it is started, then seen through UDP on 127.0.0.1 and nothing else.
"""

from __future__ import annotations

import itertools
import math
import socket
from collections.abc import Callable, Iterator
from contextlib import contextmanager

import pytest
from egm_wire import MCI_ERROR, MCI_RUNNING, MSGTYPE_DATA, Robot, read_robot, sensor

from forcelearn.devices import Pose
from forcelearn.emulators.clock import SimClock
from forcelearn.emulators.egm import EgmControllerConfig, EgmControllerEmulator
from forcelearn.emulators.physics.cell import CellPhysics
from forcelearn.emulators.physics.tool import ToolParams

START = (900.0, 0.0, 600.0)
DOWN = (0.0, 1.0, 0.0, 0.0)
ARM_RANGES_DEG = ((-170, 170), (-70, 110), (-165, -5), (-180, 180), (0, 180), (-180, 180))
"""The emulated arm's axis ranges as docs/emulators.md documents them."""
SERVO_TIME_CONSTANT_S = 0.010
"""The emulated servo's first-order lag (docs/egm.md, [emulator.egm] time_constant_s)."""
TOOL_MASS_KG = 0.9
"""The emulated tool (docs/emulators.md: a 0.9 kg roller and holder)."""

Answer = Callable[[int, Robot], bytes | None]


@contextmanager
def controller(**config: object) -> Iterator[tuple[socket.socket, bool]]:
    """A lockstep emulated controller sending to a PC socket on 127.0.0.1; yields (socket, rw7)."""
    pc = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    pc.bind(("127.0.0.1", 0))
    pc.settimeout(5.0)
    physics = CellPhysics(pose=Pose(*START, DOWN), tool=ToolParams())
    emulator = EgmControllerEmulator(
        pc.getsockname()[1], physics=physics, clock=SimClock(),
        config=EgmControllerConfig(**config),  # type: ignore[arg-type]
    )
    try:
        with emulator:
            yield pc, config.get("version", "rw7") == "rw7"
    finally:
        pc.close()


def session(cycles: int, answer: Answer, **config: object) -> list[Robot]:
    """Read ``cycles`` EgmRobot datagrams, answering each with ``answer(k, message)``."""
    seen: list[Robot] = []
    with controller(**config) as (pc, rw7):
        while len(seen) < cycles:
            data, address = pc.recvfrom(65535)
            message = read_robot(data, rw7)
            seen.append(message)
            reply = answer(len(seen) - 1, message)
            pc.sendto(reply if reply is not None else sensor(len(seen) - 1), address)
    return seen


def hold(k: int, message: Robot) -> bytes:
    """Answer with the start pose."""
    return sensor(k, START, DOWN)


def test_every_message_is_data_numbered_from_zero() -> None:
    """Manual p.35: mtype MSGTYPE_DATA from the controller; seqno +1 per message."""
    seen = session(10, hold)
    assert [m.mtype for m in seen] == [MSGTYPE_DATA] * 10
    assert [m.seqno for m in seen] == list(range(10))


def test_feedback_and_planned_joints_are_the_six_axes_in_degrees() -> None:
    """Manual p.38: feedBack.joints / planned.joints, the robot's axes, in degrees.

    Six values each, inside the emulated arm's documented ranges; J3's range
    (-165..-5 deg) cannot hold a value in radians. A move changes them.
    """
    seen = session(80, lambda k, m: sensor(k, (START[0] + 20.0, START[1], START[2]), DOWN))
    for message in (seen[0], seen[-1]):
        for joints in (message.feedback.joints, message.planned.joints):
            assert len(joints) == 6
            for angle, (low, high) in zip(joints, ARM_RANGES_DEG, strict=True):
                assert low <= angle <= high
    assert abs(seen[0].feedback.joints[2]) > 2 * math.pi  # degrees, not radians
    assert seen[-1].feedback.joints != seen[0].feedback.joints
    assert seen[-1].planned.joints != seen[0].planned.joints
    assert seen[-1].feedback.xyz == pytest.approx((START[0] + 20.0, START[1], START[2]), abs=0.01)


def test_clock_is_seconds_and_microseconds_since_1970_on_the_sample_grid() -> None:
    """EgmClock counts seconds and µs since 1970, one message per 4 ms (manual p.33).

    planned.time is "when the robot will be in the planned position" (p.38),
    so not before the feedback's.
    """
    seen = session(20, hold)
    year_2020, year_2100 = 1_577_836_800, 4_102_444_800
    clocks = []
    for message in seen:
        assert message.feedback.clock is not None and message.planned.clock is not None
        sec, usec = message.feedback.clock
        assert year_2020 <= sec < year_2100 and 0 <= usec < 1_000_000
        clocks.append(sec * 1_000_000 + usec)
        planned_sec, planned_usec = message.planned.clock
        assert planned_sec * 1_000_000 + planned_usec >= clocks[-1]
    assert {b - a for a, b in itertools.pairwise(clocks)} == {4000}


def test_rw7_measured_force_is_the_raw_sensor_force_when_force_control_is_off() -> None:
    """Manual p.36: measuredForce "will show raw sensor force when force control is not active".

    No Force Control runs: fcActive is sent false, and force holds the six
    values of the raw sensor, the tool's weight included (nothing compensated).
    """
    message = session(1, hold, version="rw7")[0]
    assert message.fc_active is False
    assert len(message.force) == 6
    weight = math.sqrt(sum(f * f for f in message.force[:3]))
    assert weight == pytest.approx(TOOL_MASS_KG * 9.80665, rel=1e-6)


def test_rw6_measured_force_is_field_one() -> None:
    """RobotWare 6 egm.proto: EgmMeasuredForce has force = 1 and no fcActive."""
    message = session(1, hold, version="rw6")[0]
    assert len(message.force) == 6 and message.fc_active is None


def ramp(speed_ref: bool) -> list[Robot]:
    """100 cycles of a 50 mm/s ramp along x, then 60 cycles holding its end; speedRef optional."""
    def answer(k: int, message: Robot) -> bytes:
        x = START[0] + 50.0 * 0.004 * min(k, 100)
        moving = speed_ref and k < 100
        return sensor(k, (x, START[1], START[2]), DOWN,
                      speed_cartesian=[50.0, 0, 0, 0, 0, 0] if moving else None)
    return session(160, answer)


def test_speed_ref_is_the_speed_feed_forward_of_the_control_law() -> None:
    """Manual p.26: speed = k (pos_ref - pos) + speed_ref, the moving target's velocity.

    On a ramp at v the steady tracking error is v / k without it and 0 with
    it; k = 1 / tau of the emulated servo. Once the target stands (speed_ref
    0) both end on it.
    """
    plain, fed = ramp(False), ramp(True)
    lag_plain = plain[99].planned.xyz[0] - plain[99].feedback.xyz[0]  # type: ignore[index]
    lag_fed = fed[99].planned.xyz[0] - fed[99].feedback.xyz[0]  # type: ignore[index]
    assert lag_plain - lag_fed == pytest.approx(50.0 * SERVO_TIME_CONSTANT_S, rel=0.02)
    end = START[0] + 50.0 * 0.4
    assert plain[-1].feedback.xyz[0] == pytest.approx(end, abs=0.01)  # type: ignore[index]
    assert fed[-1].feedback.xyz[0] == pytest.approx(end, abs=0.01)  # type: ignore[index]


def test_joint_mode_follows_planned_joints() -> None:
    """EGMSetupUC with its Joint switch (manual p.77): planned.joints guide the robot (deg)."""
    goal: list[float] = []

    def answer(k: int, message: Robot) -> bytes:
        if not goal:
            goal.extend(message.feedback.joints)
            goal[0] += 5.0
            goal[1] += 3.0
        return sensor(k, joints=goal)

    seen = session(80, answer, mode="joint")
    assert seen[-1].mci == MCI_RUNNING
    assert seen[-1].feedback.joints == pytest.approx(goal, abs=0.01)
    assert seen[-1].planned.joints == pytest.approx(goal, abs=1e-9)
    assert seen[-1].feedback.xyz != seen[0].feedback.xyz


def test_joint_mode_refuses_an_axis_out_of_range_with_mci_error() -> None:
    """A planned J2 of 130 deg is outside the arm's range: EGM stops in error (MCI_ERROR)."""
    def answer(k: int, message: Robot) -> bytes:
        joints = list(message.feedback.joints)
        joints[1] = 130.0
        return sensor(k, joints=joints)

    seen = session(10, answer, mode="joint")
    assert seen[-1].mci == MCI_ERROR
    assert seen[-1].feedback.xyz == pytest.approx(START)


def test_pose_mode_keeps_the_latest_reference_when_only_joints_come() -> None:
    """A Pose session given joints only keeps the latest reference (manual p.26).

    "If no position data had been sent, motion control continues to use the
    latest position data": joints carry no position data for a Pose session.
    """
    def answer(k: int, message: Robot) -> bytes:
        joints = list(message.feedback.joints)
        joints[0] += 10.0
        return sensor(k, joints=joints)

    seen = session(40, answer, mode="pose")
    assert seen[-1].mci == MCI_RUNNING
    assert seen[-1].feedback.xyz == pytest.approx(START)
