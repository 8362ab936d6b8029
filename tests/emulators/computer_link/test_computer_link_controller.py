"""Protocol engine of the emulated controller, frames in and answers out (no ports)."""

from __future__ import annotations

import subprocess
import sys

import pytest

from forcelearn.emulators.computer_link.controller import ControllerEngine
from forcelearn.emulators.computer_link.faults import ComputerLinkFaultConfig, Fault, FaultInjector
from forcelearn.emulators.physics.arm import HOME, ArmConfig
from forcelearn.emulators.physics.cell import CellPhysics
from forcelearn.protocols.computer_link import framing
from forcelearn.protocols.computer_link import messages as m

ACK, NAK, ENQ = framing.Control.ACK, framing.Control.NAK, framing.Control.ENQ


def _request(command: m.Command, tns: int, body: bytes = b"") -> framing.DataFrame:
    return framing.DataFrame(m.encode_request(command, tns, body))


def _move_by(tns: int, dz_mm: float) -> framing.DataFrame:
    return _request(m.Command.MOVE_BY, tns, m.increment_body((0.0, 0.0, dz_mm)))


def _reply(answer) -> m.Reply:
    consumed, frame = framing.decode(answer.wire)
    assert consumed == len(answer.wire)
    return m.decode_reply(frame.payload)


@pytest.fixture
def engine() -> ControllerEngine:
    """A fresh controller engine at its home pose, with its own physics."""
    return ControllerEngine(ArmConfig(instant=True), physics=CellPhysics())


def test_request_is_acked_then_answered_and_moves_the_physics(engine) -> None:
    """ACK, then a reply with the same transaction number; the physics sees the new pose."""
    ack, reply = engine.handle(_move_by(41, -3.0))
    assert ack.wire == ACK.wire
    assert _reply(reply) == m.Reply(m.Command.MOVE_BY, 41, m.ErrorCode.OK)
    assert engine.move_count == 1
    assert engine.physics.pose == HOME.moved(dz_mm=-3.0)


def test_retransmitted_request_is_never_executed_twice(engine) -> None:
    """The same transaction again gets ACK and the same reply bytes, without moving."""
    first = engine.handle(_move_by(7, -1.0))
    again = engine.handle(_move_by(7, -1.0))
    assert [a.wire for a in again] == [a.wire for a in first]
    assert not again[1].executed
    assert engine.move_count == 1
    engine.handle(_move_by(8, -1.0))  # a new transaction number is a new command
    assert engine.move_count == 2
    assert engine.pose == HOME.moved(dz_mm=-2.0)


def test_enq_and_nak_repeat_the_last_reply_or_nak_when_there_is_none(engine) -> None:
    """Before any reply ENQ gets NAK; afterwards ENQ and NAK both repeat the reply."""
    assert [a.wire for a in engine.handle(ENQ)] == [NAK.wire]
    _, reply = engine.handle(_request(m.Command.READ_STATUS, 3))
    assert [a.wire for a in engine.handle(ENQ)] == [reply.wire]
    assert [a.wire for a in engine.handle(NAK)] == [reply.wire]
    assert engine.handle(ACK) == []


def test_damaged_frame_gets_nak_and_changes_nothing(engine) -> None:
    """A BadFrame is answered with NAK only."""
    assert [a.wire for a in engine.handle(framing.BadFrame("CRC"))] == [NAK.wire]
    assert engine.move_count == 0


@pytest.mark.parametrize(
    ("payload", "error"),
    [
        (b"\x7e\x05\x00", m.ErrorCode.UNKNOWN_COMMAND),
        (b"\x03\x05\x00\x00", m.ErrorCode.BAD_REQUEST),
    ],
)
def test_malformed_requests_get_error_replies(engine, payload: bytes, error) -> None:
    """Unknown codes and wrong body sizes are refused with a code and a reason."""
    _, answer = engine.handle(framing.DataFrame(payload))
    _consumed, frame = framing.decode(answer.wire)
    assert frame.payload[:4] == bytes((payload[0] | 0x80, 5, 0, error))
    assert len(frame.payload) > 4  # a reason follows
    assert engine.move_count == 0


def test_refused_move_leaves_robot_and_physics_in_place(engine) -> None:
    """A target outside the workspace gets OUT_OF_WORKSPACE; nothing moves."""
    _, answer = engine.handle(_move_by(9, -900.0))
    reply = _reply(answer)
    assert reply.error == m.ErrorCode.OUT_OF_WORKSPACE
    assert "workspace" in reply.reason
    assert engine.move_count == 0
    assert engine.physics.pose == HOME
    _, status = engine.handle(_request(m.Command.READ_STATUS, 10))
    assert m.parse_status(_reply(status).body).last_error == m.ErrorCode.OUT_OF_WORKSPACE


def test_move_to_carries_the_orientation(engine) -> None:
    """An absolute move with a new quaternion reaches that orientation."""
    tilted = (0.0, 0.9238795, 0.3826834, 0.0)
    body = m.pose_body((900.0, 10.0, 600.0), tilted)
    engine.handle(_request(m.Command.MOVE_TO, 1, body))
    _, answer = engine.handle(_request(m.Command.READ_POSITION, 2))
    position = m.parse_position(_reply(answer).body)
    assert position.quaternion == pytest.approx(tilted)
    assert position.xyz_mm == (900.0, 10.0, 600.0)


def test_fault_limits_and_seeded_probability_are_deterministic() -> None:
    """Limit caps the firings; the same seed fires the same way."""
    once = FaultInjector(ComputerLinkFaultConfig(drop_request=Fault(1.0, limit=1)))
    assert [once.drop_request() for _ in range(3)] == [True, False, False]
    runs = [FaultInjector(ComputerLinkFaultConfig(drop_reply=Fault(0.5), seed=3)) for _ in range(2)]
    a = [runs[0].drop_reply() for _ in range(50)]
    b = [runs[1].drop_reply() for _ in range(50)]
    assert a == b
    assert 10 < sum(a) < 40
    twice = ComputerLinkFaultConfig(corrupt_byte=Fault(1.0, limit=2))
    corrupted = FaultInjector(twice).corrupt(bytes(5))
    assert sum(1 for byte in corrupted if byte) == 2


def test_emulator_imports_only_the_codec_of_the_driver_package() -> None:
    """The emulator knows bytes and frames, not the driver (nor pyserial).

    Only what the import adds counts: the installed ``.pth`` hook has imported
    pyserial at start-up, for the ``forcelearn-robot://`` URL handler.
    """
    code = (
        "import sys; before = set(sys.modules);"
        "import forcelearn.emulators.computer_link as e;"
        "bad = [n for n in set(sys.modules) - before if n.endswith(('computer_link.driver', "
        "'computer_link.link')) or n == 'serial'];"
        "print(bad); sys.exit(1 if bad else 0)"
    )
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60)
    assert done.returncode == 0, done.stdout + done.stderr
