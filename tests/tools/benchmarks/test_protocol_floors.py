"""The protocol floors run the protocols' own exchanges: a link move's writes, sized as sent."""

from __future__ import annotations

import pytest
import serial

from forcelearn.drivers.computer_link import ComputerLinkRobot, LinkConfig, link
from forcelearn.emulators.computer_link import ComputerLinkEmulator
from forcelearn.emulators.pty_endpoint import PtyEndpoint
from forcelearn.tools.benchmarks import protocol_floors


def test_the_link_floor_writes_what_a_move_by_writes(monkeypatch: pytest.MonkeyPatch) -> None:
    """The PC's request and ACK and the controller's one answer write: the floor's bytes' sizes.

    The transaction number and the increment differ (the bytes themselves may);
    the sizes, which are what the pty carries, must not. The link starts its transaction
    numbers at random, and a number with a DLE byte (0x10) is doubled on the wire: one run
    in about a hundred wrote 23 bytes for the floor's 22. The first number is pinned to one
    whose next few numbers carry none.
    """
    monkeypatch.setattr(link.secrets, "randbelow", lambda bound: 0x0101)
    writes: list[tuple[str, int]] = []
    pc_write, controller_write = serial.Serial.write, PtyEndpoint.write

    def record_pc(port: serial.Serial, data: bytes) -> int | None:
        writes.append(("pc", len(data)))
        return pc_write(port, data)

    def record_controller(endpoint: PtyEndpoint, data: bytes) -> None:
        writes.append(("controller", len(data)))
        controller_write(endpoint, data)

    with ComputerLinkEmulator("pty") as emulator, ComputerLinkRobot(
        LinkConfig(url=emulator.address)
    ) as robot:
        robot.move_by(dz_mm=0.05)  # the driver reads its reference first: not timed by the floor
        monkeypatch.setattr(serial.Serial, "write", record_pc)
        monkeypatch.setattr(PtyEndpoint, "write", record_controller)
        robot.move_by(dz_mm=-0.05)
        monkeypatch.undo()
    request, answer, ack = protocol_floors.link_move_frames()
    assert writes == [("pc", len(request)), ("controller", len(answer)), ("pc", len(ack))]
