"""Fault injection: the driver recovers with the robot moved exactly once, or raises clearly.

Every test runs over a pty and over TCP; the emulator's move counter is the proof.
"""

from __future__ import annotations

import pytest

from forcelearn.emulators.computer_link import ComputerLinkFaultConfig, Fault
from forcelearn.emulators.physics.arm import HOME
from forcelearn.errors import LinkError

ONCE = Fault(1.0, limit=1)


def _armed(emulator, name: str, fault: Fault = ONCE) -> None:
    """Arm one fault on a running emulator (after the driver's opening transactions)."""
    config = emulator.faults.config
    emulator.faults.config = type(config)(**{**config.__dict__, name: fault})


@pytest.mark.parametrize("fault", ["drop_request", "drop_reply", "corrupt_byte"])
def test_single_fault_is_recovered_and_the_robot_moves_once(emulator, connect, fault) -> None:
    """A lost request, a lost reply or one damaged byte: retries recover, one move executed."""
    robot = connect(emulator.address)
    _armed(emulator, fault)
    robot.move_by(dz_mm=-2.0)
    assert emulator.faults.fired[fault] == 1
    assert emulator.move_count == 1
    assert robot.read_pose() == HOME.moved(dz_mm=-2.0)


# An ACK delayed past the timeout is tested in test_computer_link_link.py against a
# scripted controller that stays silent until it has counted the ENQs: the outcome
# there never depends on how fast the host runs (it did here, by 80 ms).


def test_dropped_connection_raises_link_error_then_reconnect_works(emulator, connect) -> None:
    """The controller hangs up after executing: a clear LinkError, one move, reconnect resumes."""
    robot = connect(emulator.address)
    _armed(emulator, "drop_connection")
    with pytest.raises(LinkError, match="reconnect"):
        robot.move_by(dy_mm=4.0)
    assert emulator.move_count == 1
    with pytest.raises(LinkError, match="link is down"):
        robot.move_by(dy_mm=4.0)  # no silent reuse of a lost link
    assert emulator.move_count == 1
    robot.reconnect()
    assert robot.read_pose() == HOME.moved(dy_mm=4.0)
    robot.move_by(dy_mm=-4.0)
    assert emulator.move_count == 2


def test_random_corruption_never_moves_twice(make_emulator, connect) -> None:
    """Under 1 % byte corruption each way, every move executes once or raises a LinkError."""
    emulator = make_emulator(faults=ComputerLinkFaultConfig(corrupt_byte=Fault(0.01), seed=7))
    robot = connect(emulator.address, nak_retries=3, enq_retries=3)
    succeeded = failed = 0
    for i in range(60):
        before = emulator.move_count
        try:
            robot.move_by(dz_mm=0.5 if i % 2 else -0.5)
        except LinkError:
            failed += 1
            assert emulator.move_count - before in (0, 1)
        else:
            succeeded += 1
            assert emulator.move_count - before == 1
    assert emulator.faults.fired["corrupt_byte"] > 10
    assert succeeded > 40


def test_retransmissions_stop_at_the_documented_count(emulator, connect) -> None:
    """A controller that loses every request sees exactly 1 + nak_retries copies, then LinkError."""
    robot = connect(emulator.address, nak_retries=2, enq_retries=3)
    _armed(emulator, "drop_request", Fault(1.0))
    with pytest.raises(LinkError, match="lost 3 times"):
        robot.move_by(dz_mm=1.0)
    assert emulator.faults.fired["drop_request"] == 3
    assert emulator.move_count == 0
