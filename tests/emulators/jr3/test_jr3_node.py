"""The emulated adapter node, spoken to frame by frame with the codec (no driver)."""

from __future__ import annotations

import itertools
import os
from collections.abc import Iterator

import can
import numpy as np
import pytest

from forcelearn.emulators.jr3 import FaultConfig, Jr3EmulatorNode
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
    """Each host command gets its ACK; full-scale queries carry N and dN*m; SYNC gets a pair."""
    node, host = wire
    assert _messages(_ask(host, codec.GetState())) == [Ack(1)]
    assert _messages(_ask(host, codec.StartSync(12500))) == [Ack(0)]
    assert _messages(_ask(host, codec.GetState())) == [Ack(0)]
    assert _messages(_ask(host, codec.GetForceFullScales())) == [Ack(0, (200, 200, 400))]
    assert _messages(_ask(host, codec.GetMomentFullScales())) == [Ack(0, (200, 200, 200))]
    assert _messages(_ask(host, codec.SetFilter(781))) == [Ack(0)]
    assert node.cutoff_hz == 7.81
    assert _messages(_ask(host, codec.ZeroOffsets())) == [Ack(0)]
    forces, moments = _messages(_ask(host, codec.Sync(), replies=2))
    assert isinstance(forces, codec.Forces) and isinstance(moments, codec.Moments)
    assert forces.counter == moments.counter == 0
    assert _messages(_ask(host, codec.Stop())) == [Ack(0)]
    assert _messages(_ask(host, codec.StartAsync(200, 10_000))) == [Ack(0)]
    assert node.period_us == 10_000
    assert _messages(_ask(host, codec.Reset(), replies=2)) == [Ack(0), codec.Bootup()]
    assert (node.mode, node.initialised, node.counter) == ("idle", False, 0)


def test_refuses_a_zero_period_or_cutoff(wire: tuple[Jr3EmulatorNode, can.BusABC]) -> None:
    """A start with period 0 or cut-off 0 is answered not-ready and changes nothing."""
    node, host = wire
    assert _messages(_ask(host, codec.StartAsync(200, 0))) == [Ack(1)]
    assert _messages(_ask(host, codec.StartSync(0))) == [Ack(1)]
    assert node.mode == "idle"


def test_ignores_other_nodes_and_counts_malformed_commands(
    wire: tuple[Jr3EmulatorNode, can.BusABC],
) -> None:
    """Commands for node 4 get no answer; a wrong-length command is counted, not answered."""
    node, host = wire
    host.send(can.Message(arbitration_id=0x404, data=b"", is_extended_id=False))
    host.send(can.Message(arbitration_id=0x183, data=b"\x01", is_extended_id=False))
    assert host.recv(0.1) is None
    assert node.stats.rejected_by_reason == {"BAD_LENGTH": 1}


def test_silent_node_sends_nothing(wire: tuple[Jr3EmulatorNode, can.BusABC]) -> None:
    """A silent node neither acknowledges nor samples."""
    node, host = wire
    node.set_faults(FaultConfig(silent=True))
    host.send(can.Message(arbitration_id=0x403, data=b"", is_extended_id=False))
    assert host.recv(0.1) is None


def test_drop_and_corrupt_probabilities(wire: tuple[Jr3EmulatorNode, can.BusABC]) -> None:
    """With 30 % drops and 20 % corrupt lengths, the frames seen match those rates (+-0.08)."""
    node, host = wire
    _ask(host, codec.StartSync(12500))
    node.set_faults(FaultConfig(drop_probability=0.3, corrupt_length_probability=0.2))
    sync = can.Message(arbitration_id=0x080, data=b"", is_extended_id=False)
    for _ in range(500):
        host.send(sync)
    results = []
    while (msg := host.recv(0.2)) is not None:
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
    assert np.all(np.diff([r[6] for r in runs[0]]) == 1)
