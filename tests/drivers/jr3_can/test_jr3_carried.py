"""A SYNC carried through the in-process bus unframed reads what its frames read, to the bit.

``Jr3EmulatorBus.carry_sync`` hands the node's answer to the driver as its six counts
(no CAN frame encoded, sent, received or decoded); the clock, the bus times, the
sensor model's draws, the counters and every sample must be those of the frames.
"""

from __future__ import annotations

import itertools
import os
from typing import Any

import can
import numpy as np
import pytest

from forcelearn.devices import Pose
from forcelearn.drivers.jr3_can.config import Jr3Config
from forcelearn.drivers.jr3_can.driver import Jr3CanSensor
from forcelearn.emulators.jr3 import Jr3EmulatorNode
from forcelearn.emulators.jr3.can_bus import Jr3EmulatorBus
from forcelearn.emulators.jr3.firmware import Jr3Firmware
from forcelearn.emulators.physics.cell import CellPhysics
from forcelearn.emulators.physics.sponge import Sponge

_numbers = itertools.count()


def _plain(value: Any) -> Any:
    """A state dict with arrays as lists (comparable with ==)."""
    if isinstance(value, dict):
        return {k: _plain(v) for k, v in value.items()}
    if isinstance(value, np.ndarray):
        return value.tolist()
    return value


def _session(carries: bool, monkeypatch: pytest.MonkeyPatch) -> tuple[list[Any], int]:
    """Reads in free space and pressed into a sponge; what was read and the carried SYNCs."""
    monkeypatch.setattr(Jr3EmulatorBus, "carries", carries)
    carried = 0
    original = Jr3Firmware._carry_sync

    def counting(self: Jr3Firmware, node_id: int) -> Any:
        nonlocal carried
        answer = original(self, node_id)
        carried += answer is not None
        return answer

    monkeypatch.setattr(Jr3Firmware, "_carry_sync", counting)
    physics = CellPhysics(Sponge(), pose=Pose(0.0, 0.0, 30.0))
    channel = f"jr3-carried-{os.getpid()}-{next(_numbers)}"
    seen: list[Any] = []
    with Jr3EmulatorNode(physics, channel=channel, in_process=True, seed=4) as node, \
            can.Bus(interface="forcelearn-jr3", channel=channel) as bus, \
            Jr3CanSensor(bus, Jr3Config(zero_settle_s=0.01)) as sensor:
        for z in (30.0, 15.0, 12.5, 8.0, 30.0):
            physics.set_pose(Pose(0.0, 0.0, z))
            samples = [sensor.read(), *sensor.read_many(7, window=2)]
            seen += [(s.wrench.tobytes(), s.counter, s.saturated, s.sensor_dt_s)
                     for s in samples]
        sensor.zero_offsets()
        seen += [sensor.read().wrench.tobytes(), physics.clock.now_s]
        seen += [_plain(node.state_dict()), node.stats, sensor.stats]
    return seen, carried


def test_carried_syncs_read_what_framed_syncs_read(monkeypatch: pytest.MonkeyPatch) -> None:
    """Samples, counters, clock, node state and counts equal; the fast path was taken."""
    carried, taken = _session(True, monkeypatch)
    framed, none = _session(False, monkeypatch)
    assert none == 0
    assert taken == 5 * (1 + 7) + 1  # every SYNC went carried
    assert carried == framed


@pytest.mark.parametrize("route", ["callback", "pending frame", "plain"])
def test_a_carried_sample_is_its_two_messages(route: str) -> None:
    """``on_carried_sample`` leaves the listener as ``on_carried_all`` of Forces, Moments."""
    from forcelearn.drivers.jr3_can.listener import Jr3Listener
    from forcelearn.protocols.jr3_can import codec
    from forcelearn.protocols.jr3_can.opcodes import DEFAULT_OPCODES

    def listener() -> tuple[Jr3Listener, list[Any]]:
        lst = Jr3Listener(1, DEFAULT_OPCODES, 16000)
        lst.set_full_scales(np.array([100.0, 100.0, 200.0, 10.0, 10.0, 10.0]))
        got: list[Any] = []
        if route == "callback":
            lst.callbacks.append(got.append)
        if route == "pending frame":
            lst.on_carried(codec.Moments((1, 2, 3), 9))
        return lst, got

    def state(lst: Jr3Listener, got: list[Any]) -> Any:
        latest = lst.latest
        sample = None if latest is None else (latest.wrench.tobytes(), latest.counter,
                                              latest.saturated, latest.sensor_dt_s)
        return (lst.seq, lst.data_frames, lst.stats(), lst._pairer.__dict__, sample, len(got))

    counts = [((10, -20, 16001, 4, 5, -6), 7), ((1, 2, 3, 4, 5, 6), 9), ((0,) * 6, 9),
              ((7, 7, 7, 7, 7, 7), 12)]
    one, seen_one = listener()
    two, seen_two = listener()
    for raw, counter in counts:
        one.on_carried_sample(raw, counter)
        two.on_carried_all([codec.Forces(raw[:3], counter), codec.Moments(raw[3:], counter)])
        assert state(one, seen_one) == state(two, seen_two)
    assert one.seq >= 2


def _batch_session(batched: bool, drop_every: int, monkeypatch: pytest.MonkeyPatch
                   ) -> list[Any]:
    """read_many over the in-process bus, its SYNCs carried in one call or one by one.

    Every ``drop_every``-th carried answer is lost before the listener (no sample: the
    driver waits, counts the SYNC unanswered and sends another).
    """
    from forcelearn.drivers.jr3_can.listener import Jr3Listener

    if not batched:
        monkeypatch.setattr(Jr3EmulatorBus, "carry_syncs", None)
    answers = itertools.count(1)
    original = Jr3Listener.on_carried_sample

    def lossy(self: Jr3Listener, raw: Any, counter: int) -> None:
        if next(answers) % drop_every:
            original(self, raw, counter)

    monkeypatch.setattr(Jr3Listener, "on_carried_sample", lossy)
    physics = CellPhysics(Sponge(), pose=Pose(0.0, 0.0, 30.0))
    channel = f"jr3-batch-{os.getpid()}-{next(_numbers)}"
    seen: list[Any] = []
    with Jr3EmulatorNode(physics, channel=channel, in_process=True, seed=5) as node, \
            can.Bus(interface="forcelearn-jr3", channel=channel) as bus, \
            Jr3CanSensor(bus, Jr3Config(zero_settle_s=0.01, stale_timeout_s=0.02)) as sensor:
        for z in (30.0, 12.5, 8.0):
            physics.set_pose(Pose(0.0, 0.0, z))
            seen += [(s.wrench.tobytes(), s.counter, s.sensor_dt_s)
                     for s in sensor.read_many(9)]
        seen += [physics.clock.now_s, _plain(node.state_dict()), node.stats, sensor.stats]
    monkeypatch.undo()
    return seen


@pytest.mark.parametrize("drop_every", [4, 1000])
def test_read_many_carried_in_one_call_reads_what_it_reads_one_by_one(
        drop_every: int, monkeypatch: pytest.MonkeyPatch) -> None:
    """``Jr3EmulatorBus.carry_syncs``: samples, clock, node and driver counts equal."""
    calls: list[int] = []
    original = Jr3EmulatorBus.carry_syncs

    def counting(self: Jr3EmulatorBus, node_id: int, count: int, take: Any) -> int | None:
        calls.append(count)
        return original(self, node_id, count, take)

    monkeypatch.setattr(Jr3EmulatorBus, "carry_syncs", counting)
    batched = _batch_session(True, drop_every, monkeypatch)
    assert calls and max(calls) == 9  # the batch route was taken
    single = _batch_session(False, drop_every, monkeypatch)
    assert batched == single


def test_a_sample_is_scaled_as_counts_to_wrench_to_the_bit() -> None:
    """The listener's six products (floats) are ``scaling.counts_to_wrench`` (numpy) exactly."""
    import random

    from forcelearn.drivers.jr3_can.listener import Jr3Listener
    from forcelearn.protocols.jr3_can.opcodes import DEFAULT_OPCODES
    from forcelearn.protocols.jr3_can.scaling import counts_to_wrench

    rng = random.Random(2)
    for _ in range(50):
        scales = np.array([rng.uniform(10.0, 2000.0) for _ in range(3)]
                          + [rng.uniform(1.0, 200.0) for _ in range(3)])
        lst = Jr3Listener(1, DEFAULT_OPCODES, 16000)
        lst.set_full_scales(scales)
        for counter in range(20):
            raw = tuple(rng.choice((rng.randint(-32768, 32767), 0, 32767, -32768, 1))
                        for _ in range(6))
            lst.on_carried_sample(raw, counter)  # type: ignore[arg-type]
            assert lst.latest is not None
            assert lst.latest.wrench.tobytes() == counts_to_wrench(raw, scales).tobytes()


def _reads(wrap: bool) -> tuple[list[Any], int]:
    """Reads pressed into a sponge, with or without a wrapper on the node's ``_emit_sample``."""
    physics = CellPhysics(Sponge(), pose=Pose(0.0, 0.0, 12.5))
    channel = f"jr3-wrapped-{os.getpid()}-{next(_numbers)}"
    seen: list[Any] = []
    emitted = 0
    with Jr3EmulatorNode(physics, channel=channel, in_process=True, seed=6) as node, \
            can.Bus(interface="forcelearn-jr3", channel=channel) as bus, \
            Jr3CanSensor(bus, Jr3Config(zero_settle_s=0.01)) as sensor:
        if wrap:
            emit = node._emit_sample

            def counted() -> None:
                nonlocal emitted
                emitted += 1
                emit()

            node._emit_sample = counted  # type: ignore[method-assign]
        seen += [(s.wrench.tobytes(), s.counter) for s in sensor.read_many(6)]
        seen += [sensor.read().wrench.tobytes(), physics.clock.now_s, node.stats.samples]
    return seen, emitted


def test_a_wrapped_emit_sample_sees_every_sample_and_reads_the_same() -> None:
    """A tool that wraps ``_emit_sample`` (step_timeline) gets the frames' route: same reads."""
    wrapped, emitted = _reads(True)
    plain, none = _reads(False)
    assert none == 0 and emitted == 7
    assert wrapped == plain
