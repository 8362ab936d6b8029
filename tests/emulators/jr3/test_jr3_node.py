"""The emulated adapter node, spoken to frame by frame with the codec (no driver)."""

from __future__ import annotations

import itertools
import os
from collections.abc import Iterator

import can
import numpy as np
import pytest

from forcelearn.emulators.jr3 import Jr3EmulatorNode, Jr3FaultConfig
from forcelearn.emulators.physics.cell import CellPhysics
from forcelearn.protocols.jr3_can import codec
from forcelearn.protocols.jr3_can.codec import Ack, Decoded, Rejected

_numbers = itertools.count()
NODE = 3


@pytest.fixture
def wire() -> Iterator[tuple[Jr3EmulatorNode, can.BusABC]]:
    """A node (id 3) and a host bus on a private virtual channel; closed and joined after."""
    channel = f"jr3-node-{os.getpid()}-{next(_numbers)}"
    node = Jr3EmulatorNode(CellPhysics(), channel=channel, node_id=NODE, seed=1)
    with can.Bus(interface="virtual", channel=channel) as host:
        yield node, host
        node.close()


def _ask(host: can.BusABC, message: codec.Message, replies: int = 1) -> list[Decoded | Rejected]:
    frame = codec.encode(message, NODE)
    host.send(can.Message(arbitration_id=frame.arbitration_id, data=frame.data,
                          is_extended_id=False))
    out: list[Decoded | Rejected] = []
    while len(out) < replies:
        msg = host.recv(1.0)
        assert msg is not None, f"no reply to {message}"
        result = codec.decode(msg.arbitration_id, msg.data)
        streamed = isinstance(result, Decoded) and result.message.kind in ("forces", "moments")
        if isinstance(message, codec.Sync) or not streamed:  # skip async samples
            out.append(result)
    return out


def _messages(results: list[Decoded | Rejected]) -> list[codec.Message]:
    assert all(isinstance(r, Decoded) and r.node_id == NODE for r in results)
    return [r.message for r in results]  # type: ignore[union-attr]


def test_answers_every_command(wire: tuple[Jr3EmulatorNode, can.BusABC]) -> None:
    """Each host command gets its ACK; full-scale queries carry N and dN*m; SYNC gets a pair.

    As the firmware: ready (status 0) from power-up; a reset is ACKed ready with no bootup
    frame, and leaves the sensor stopped with the counter at 0. (This test used to expect
    status 1 before the first start and a bootup after reset: the old, wrong emulator.)
    """
    node, host = wire
    assert _messages(_ask(host, codec.GetState())) == [Ack(0)]
    assert _messages(_ask(host, codec.StartSync(12500))) == [Ack(0)]
    assert _messages(_ask(host, codec.GetState())) == [Ack(0)]
    assert _messages(_ask(host, codec.GetForceFullScales())) == [Ack(0, (200, 200, 400))]
    assert _messages(_ask(host, codec.GetMomentFullScales())) == [Ack(0, (200, 200, 200))]
    assert _messages(_ask(host, codec.SetFilter(781))) == [Ack(0)]
    assert node.cutoff_hz == 7.81
    assert _messages(_ask(host, codec.ZeroOffsets())) == [Ack(0)]
    forces, moments = _messages(_ask(host, codec.Sync(), replies=2))
    assert isinstance(forces, codec.Forces) and isinstance(moments, codec.Moments)
    assert forces.counter == moments.counter > 0  # sensor frames since the start
    assert _messages(_ask(host, codec.Stop())) == [Ack(0)]
    assert _messages(_ask(host, codec.StartAsync(200, 10_000))) == [Ack(0)]
    assert node.period_us == 10_000
    assert _messages(_ask(host, codec.Reset())) == [Ack(0)]
    assert (node.mode, node.initialised, node.counter) == ("idle", True, 0)
    assert node.stats.bootups == 0


def test_cutoff_zero_starts_unfiltered(wire: tuple[Jr3EmulatorNode, can.BusABC]) -> None:
    """Cutoff zero starts unfiltered.

    A start with cut-off 0 is accepted (ACK ready): the adapter sends unfiltered data. (This test
    used to expect a refusal: the old, wrong emulator.)
    """
    node, host = wire
    assert _messages(_ask(host, codec.StartSync(0))) == [Ack(0)]
    assert (node.mode, node.cutoff_hz) == ("sync", 0.0)


def test_ignores_other_nodes_and_reads_short_payloads_as_zero(
    wire: tuple[Jr3EmulatorNode, can.BusABC],
) -> None:
    """Ignores other nodes and reads short payloads as zero.

    Commands for node 4 get no answer; a start sync with one payload byte is taken as cut-off 0 (a
    field whose bytes are not all there reads 0) and ACKed, as the firmware. (This test used to
    expect the short command rejected: the old, wrong emulator.)
    """
    node, host = wire
    host.send(can.Message(arbitration_id=0x404, data=b"", is_extended_id=False))
    host.send(can.Message(arbitration_id=0x183, data=b"\x01", is_extended_id=False))
    msg = host.recv(1.0)
    assert msg is not None and (msg.arbitration_id, bytes(msg.data)) == (0x103, b"\x00")
    assert host.recv(0.1) is None
    assert (node.mode, node.cutoff_hz) == ("sync", 0.0)
    assert node.stats.rejected_by_reason == {"NOT_FOR_THIS_NODE": 1}


def test_silent_node_sends_nothing(wire: tuple[Jr3EmulatorNode, can.BusABC]) -> None:
    """A silent node neither acknowledges nor samples."""
    node, host = wire
    node.set_faults(Jr3FaultConfig(silent=True))
    host.send(can.Message(arbitration_id=0x403, data=b"", is_extended_id=False))
    assert host.recv(0.1) is None


def test_drop_and_corrupt_probabilities() -> None:
    """With 30 % drops and 20 % corrupt lengths, the frames seen match those rates (+-0.08)."""
    channel = f"jr3-faults-{os.getpid()}-{next(_numbers)}"
    with Jr3EmulatorNode(CellPhysics(), channel=channel, node_id=NODE, seed=1,
                         in_process=True) as node, \
            can.Bus(interface="forcelearn-jr3", channel=channel) as host:
        _ask(host, codec.StartSync(12500))
        node.set_faults(Jr3FaultConfig(drop_probability=0.3, corrupt_length_probability=0.2))
        sync = can.Message(arbitration_id=0x080, data=b"", is_extended_id=False)
        results = []
        for _ in range(500):  # one SYNC per loop turn: the host waits for each answer
            host.send(sync)
            while (msg := host.recv(0)) is not None:
                results.append(codec.decode(msg.arbitration_id, msg.data))
    received = len(results) / 1000
    bad = sum(isinstance(r, Rejected) for r in results) / max(len(results), 1)
    assert received == pytest.approx(0.7, abs=0.08)
    assert bad == pytest.approx(0.2, abs=0.08)


def test_same_seed_same_samples_and_state_resume() -> None:
    """Two nodes, one seed: identical counts; a restored node (and clock) continues alike."""

    def run(node: Jr3EmulatorNode, host: can.BusABC, n: int) -> list[tuple[int, ...]]:
        out = []
        for _ in range(n):
            forces, moments = _messages(_ask(host, codec.Sync(), replies=2))
            out.append((*forces.raw, *moments.raw, forces.counter))  # type: ignore[union-attr]
        return out

    runs = []
    for _ in range(2):
        physics = CellPhysics()
        channel = f"jr3-seed-{os.getpid()}-{next(_numbers)}"
        with Jr3EmulatorNode(physics, channel=channel, node_id=NODE, seed=42) as node, \
                can.Bus(interface="virtual", channel=channel) as host:
            _ask(host, codec.StartSync(12500))
            first = run(node, host, 20)
            state, clock = node.state_dict(), physics.clock.state_dict()
            second = run(node, host, 20)
            node.load_state_dict(state)
            physics.clock.load_state_dict(clock)
            assert run(node, host, 20) == second
            runs.append(first + second)
    assert runs[0] == runs[1]
    assert len({r[:6] for r in runs[0]}) > 30  # noise makes them differ sample to sample
    steps = np.diff([r[6] for r in runs[0]]) % 65536
    assert set(steps.tolist()) <= {7, 8}  # one answer per 1 ms turn, 128.5 µs frames
