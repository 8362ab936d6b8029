"""The in-process link's carried payloads answer as the frames do (``ControllerEngine.carry``).

The short cut skips the framing (DLE stuffing, the check, parsing) on both
sides; the controller's clock, wires, execution, retransmission rule and reply
payloads must be those of the frames, to the bit.
"""

from __future__ import annotations

import os

import pytest

from forcelearn.devices import Pose
from forcelearn.drivers.computer_link import ComputerLinkRobot, LinkConfig, link
from forcelearn.emulators.clock import serial_char_time_s
from forcelearn.emulators.computer_link import ComputerLinkEmulator
from forcelearn.emulators.computer_link.controller import ControllerEngine
from forcelearn.emulators.physics.arm import ArmConfig
from forcelearn.emulators.physics.cell import CellPhysics
from forcelearn.protocols.computer_link import framing
from forcelearn.protocols.computer_link import messages as m

ACK, ENQ = framing.Control.ACK, framing.Control.ENQ


def _state(engine: ControllerEngine) -> tuple[object, ...]:
    return (engine.clock.now_s, engine.state_dict(), engine.motion.state_dict(),
            engine.move_count, engine.physics.pose)


def test_encoded_size_is_the_length_of_the_frame() -> None:
    """Payloads with DLE bytes anywhere, and of length 16 (a DLE length byte)."""
    rng_payloads = [os.urandom(n) for n in range(1, framing.MAX_PAYLOAD + 1)]
    dle = [b"\x10" * n for n in (1, 2, 16, 17)] + [b"\x01" * 16]
    for payload in rng_payloads + dle:
        assert framing.encoded_size(payload) == len(framing.encode(payload))


def test_a_carried_request_is_answered_as_its_frame() -> None:
    """Moves, status polls, a retransmission, a refusal, a bad request and an ENQ after."""
    char = serial_char_time_s(9600)
    framed = ControllerEngine(ArmConfig(), CellPhysics(), char)
    carried = ControllerEngine(ArmConfig(), CellPhysics(), char)
    home = framed.motion.target
    far = Pose(home.x_mm + 1e4, home.y_mm, home.z_mm, home.quaternion)
    near = home.moved(dz_mm=-5.0)
    requests = [
        m.encode_request(m.Command.SET_SPEED, 1, m.speed_body(80.0)),
        m.encode_request(m.Command.MOVE_TO, 2, m.pose_body(
            (near.x_mm, near.y_mm, near.z_mm), near.quaternion)),
        m.encode_request(m.Command.MOVE_TO, 2, m.pose_body(  # a retransmission
            (near.x_mm, near.y_mm, near.z_mm), near.quaternion)),
        *(m.encode_request(m.Command.READ_STATUS, 3 + i) for i in range(40)),
        m.encode_request(m.Command.MOVE_TO, 50, m.pose_body(
            (far.x_mm, far.y_mm, far.z_mm), far.quaternion)),  # refused: out of reach
        m.encode_request(m.Command.READ_POSITION, 51),
        bytes((0x7F, 52, 0)),  # an unknown command
        m.encode_request(m.Command.READ_STATUS, 53),
    ]
    for payload in requests:
        answers = framed.handle(framing.DataFrame(payload))
        framed.handle(ACK)  # the PC's ACK of the reply
        assert [a.kind for a in answers] == ["ack", "reply"]
        frame = framing.decode(answers[1].wire).frame
        assert isinstance(frame, framing.DataFrame)
        assert carried.carry(payload) == frame.payload
        assert _state(carried) == _state(framed)
    assert carried.move_count == 1  # the retransmission was not executed
    assert [a.wire for a in carried.handle(ENQ)] == [a.wire for a in framed.handle(ENQ)]
    assert _state(carried) == _state(framed)


def _session(carries: bool) -> tuple[list[object], tuple[object, ...], int]:
    """A driver's moves and waits over ``forcelearn-robot://``, frames or carried payloads."""
    emulator = ComputerLinkEmulator("inproc", config=ArmConfig(),
                                    char_time_s=serial_char_time_s(115200))
    emulator.carries = carries
    seen: list[object] = []
    with emulator, ComputerLinkRobot(LinkConfig(url=emulator.address)) as robot:
        start = robot.read_pose()
        robot.set_speed(60.0)
        for dz in (-4.0, 2.5, -0.5):
            robot.move_to(start.moved(dz_mm=dz))
            seen += [robot.wait_in_position(5.0, settle_s=0.05), robot.read_pose()]
            seen.append(robot.read_status())
        seen += [robot.read_target(), robot.read_joints_deg()]
        state = _state(emulator.engine)
    return seen, state, emulator.bytes_received


def test_a_driver_over_carried_payloads_sees_what_it_sees_over_frames(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """Replies, waits, clock, wires, arm and the bytes counted as received agree exactly.

    The transaction numbers start at 0x0FFE in both (a DLE in every later request's
    high byte: stuffed on the wire, counted in ``bytes_received``).
    """
    monkeypatch.setattr(link.secrets, "randbelow", lambda _n: 0x0FFE)
    carried = _session(carries=True)
    framed = _session(carries=False)
    assert carried == framed


def test_a_carried_status_is_what_the_carried_reply_parses_to() -> None:
    """Status polls through a move, a repeated poll and an ENQ: statuses, replies and state."""
    char = serial_char_time_s(9600)
    by_payload = ControllerEngine(ArmConfig(), CellPhysics(), char)
    by_status = ControllerEngine(ArmConfig(), CellPhysics(), char)
    home = by_payload.motion.target
    move = m.encode_request(m.Command.MOVE_TO, 1, m.pose_body(
        (home.x_mm, home.y_mm, home.z_mm - 3.0), home.quaternion))
    assert by_status.carry_status(move) is None  # not a status request: nothing done
    assert by_payload.carry(move) == by_status.carry(move)
    polls = [m.encode_request(m.Command.READ_STATUS, 2 + i) for i in range(60)]
    polls.insert(30, polls[29])  # a retransmitted poll: its reply repeated, not executed
    statuses = []
    for payload in polls:
        reply = m.decode_reply(by_payload.carry(payload))
        status = by_status.carry_status(payload)
        assert status == m.parse_status(reply.body)
        assert by_status._last_payload == by_payload._last_payload
        assert _state(by_status) == _state(by_payload)
        statuses.append(status)
    assert {s.in_position for s in statuses} == {False, True}
    assert [a.wire for a in by_status.handle(ENQ)] == [a.wire for a in by_payload.handle(ENQ)]


@pytest.mark.parametrize("asked_again", ["repeat", "enq"])
def test_a_carried_status_reply_is_encoded_only_when_asked_again(asked_again: str) -> None:
    """A poll's reply payload is kept as its status until a repeat or a DLE ENQ asks for it."""
    char = serial_char_time_s(9600)
    by_payload = ControllerEngine(ArmConfig(), CellPhysics(), char)
    by_status = ControllerEngine(ArmConfig(), CellPhysics(), char)
    poll = m.encode_request(m.Command.READ_STATUS, 7)
    reply = by_payload.carry(poll)
    status = by_status.carry_status(poll)
    assert by_status._payload is None and by_status._status_reply == (7, status)
    assert _state(by_status) == _state(by_payload)  # the wires charged the reply's length
    if asked_again == "repeat":
        assert by_status.carry(poll) == by_payload.carry(poll) == reply
    else:
        assert [a.wire for a in by_status.handle(ENQ)] == [a.wire for a in by_payload.handle(ENQ)]
    assert by_status._payload == reply and by_status._status_reply is None
    assert _state(by_status) == _state(by_payload)


def test_the_driver_takes_the_carried_status(monkeypatch: pytest.MonkeyPatch) -> None:
    """Status polls over ``forcelearn-robot://`` go by ``carry_status`` (the route tested above)."""
    calls = []
    original = ControllerEngine.carry_status

    def counting(self: ControllerEngine, payload: bytes) -> m.Status | None:
        calls.append(payload)
        return original(self, payload)

    monkeypatch.setattr(ControllerEngine, "carry_status", counting)
    _session(carries=True)
    assert len(calls) >= 6
