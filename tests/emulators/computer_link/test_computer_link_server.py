"""The running emulator: transports, one client at a time, clean shutdown, command line."""

from __future__ import annotations

import socket
import subprocess
import sys

import pytest
import serial

from forcelearn.emulators.computer_link import ArmConfig, ComputerLinkEmulator
from forcelearn.emulators.physics.arm import HOME
from forcelearn.emulators.physics.cell import CellPhysics
from forcelearn.protocols.computer_link import framing
from forcelearn.protocols.computer_link import messages as m


def _status_exchange(port: serial.SerialBase, tns: int) -> bytes:
    """Send READ_STATUS by hand and return what comes back (ACK + reply)."""
    port.write(framing.encode(m.encode_request(m.Command.READ_STATUS, tns)))
    reader, frames = framing.FrameReader(), []
    for _ in range(100):
        frames += reader.feed(port.read(64))
        if len(frames) >= 2:
            break
    return frames


@pytest.mark.parametrize("transport", ["pty", "tcp"])
def test_raw_client_gets_ack_and_reply(transport: str) -> None:
    """A bare pyserial client speaking the frames by hand is served on either transport."""
    with ComputerLinkEmulator(transport) as emu:
        port = serial.serial_for_url(emu.address, timeout=0.02)
        try:
            ack, reply = _status_exchange(port, 500)
        finally:
            port.close()
    assert ack is framing.Control.ACK
    assert m.decode_reply(reply.payload).transaction == 500


def test_tcp_serves_one_client_at_a_time_and_the_next_after_a_disconnect() -> None:
    """A second TCP client is closed at once; after the first leaves, a new one is served."""
    with ComputerLinkEmulator("tcp") as emu:
        host, port_number = emu.address.removeprefix("socket://").split(":")
        first = socket.create_connection((host, int(port_number)), timeout=2)
        first.sendall(framing.Control.ENQ.wire)
        assert first.recv(2) == framing.Control.NAK.wire  # served (nothing to repeat yet)
        second = socket.create_connection((host, int(port_number)), timeout=2)
        assert second.recv(16) == b""  # refused: closed by the emulator
        second.close()
        first.close()
        client = serial.serial_for_url(emu.address, timeout=0.02)
        try:
            ack, _ = _status_exchange(client, 1)
        finally:
            client.close()
    assert ack is framing.Control.ACK


def test_stop_joins_the_thread_and_frees_the_port() -> None:
    """After stop() the listener is closed, and stop() twice is harmless."""
    emu = ComputerLinkEmulator("tcp")
    url = emu.start()
    emu.close()
    emu.close()
    assert emu._thread is None
    _, port_number = url.removeprefix("socket://").split(":")
    with pytest.raises(OSError):
        socket.create_connection(("127.0.0.1", int(port_number)), timeout=1).close()


def test_emulator_writes_home_into_the_shared_physics() -> None:
    """The physics object handed in learns the robot's pose at start."""
    physics = CellPhysics()
    with ComputerLinkEmulator("pty", physics=physics, config=ArmConfig()):
        assert physics.pose == HOME


def test_command_line_prints_the_url_it_serves_on() -> None:
    """``python -m forcelearn.emulators.computer_link`` prints a socket URL on 127.0.0.1."""
    proc = subprocess.Popen(
        [sys.executable, "-m", "forcelearn.emulators.computer_link", "--transport", "tcp"],
        stdout=subprocess.PIPE,
        text=True,
    )
    try:
        line = proc.stdout.readline().strip()
    finally:
        proc.terminate()
        proc.wait(timeout=10)
        proc.stdout.close()
    assert line.startswith("socket://127.0.0.1:")
