"""The driver against the emulated adapter on the virtual bus: init, scaling, zeroing, modes."""

from __future__ import annotations

import itertools
import os
import time
from collections.abc import Callable
from pathlib import Path

import can
import numpy as np
import pytest

from forcelearn.devices import ForceSensor, Pose
from forcelearn.drivers.jr3_can.config import Jr3Config
from forcelearn.drivers.jr3_can.driver import Jr3CanSensor
from forcelearn.emulators.jr3 import Jr3EmulatorNode, Jr3ModelParams
from forcelearn.emulators.jr3 import firmware as firmware_module
from forcelearn.emulators.physics.cell import CellPhysics
from forcelearn.emulators.physics.tool import ToolParams
from forcelearn.errors import ConfigError, SensorBusError, SensorError, SensorTimeout

QUIET = Jr3ModelParams(noise_std=(0.0,) * 6, initial_bias=(0.0,) * 6,
                          bias_drift_per_sqrt_s=(0.0,) * 6)
TILTED = Pose(0.0, 0.0, 0.0, (0.9, 0.3, -0.2, 0.25))  # gravity shows on all six axes
TOOL = ToolParams(mass_kg=2.0, com_mm=(30.0, -20.0, 80.0))

NodeFactory = Callable[..., Jr3EmulatorNode]
SensorFactory = Callable[..., Jr3CanSensor]


def _ids(channel: str, action: Callable[[], None]) -> list[int]:
    """Return the identifiers seen on the channel while ``action`` runs."""
    with can.Bus(interface="virtual", channel=channel) as spy:
        action()
        ids = []
        while (msg := spy.recv(0.0)) is not None:
            ids.append(msg.arbitration_id)
    return ids


@pytest.mark.parametrize("route", ["virtual"])  # spies or breaks the virtual bus itself
def test_initialisation_follows_the_careful_host_sequence(
    make_node: NodeFactory, make_sensor: SensorFactory, channel: str
) -> None:
    """Get state, start sync with the cut-off, read force and moment full scales, zero; then run."""
    node = make_node(node_id=5)
    sensor = make_sensor(node_id=5, cutoff_hz=31.25, zero_on_init=True)
    assert isinstance(sensor, ForceSensor)
    ids = _ids(channel, sensor.initialise)
    commands = [i for i in ids if i & 0x7F == 5 and i >> 7 in (3, 8, 9, 10, 6)]
    assert commands == [0x405, 0x185, 0x485, 0x505, 0x305]
    assert node.mode == "sync" and node.initialised and node.cutoff_hz == 31.25
    assert np.allclose(sensor.full_scales, node.model.params.full_scales)


def test_async_initialisation_sends_cutoff_and_period(
    make_node: NodeFactory, make_sensor: SensorFactory
) -> None:
    """Async start carries the cut-off and the period, and samples stream without SYNC."""
    node = make_node()
    sensor = make_sensor(mode="async", cutoff_hz=2.0, period_us=2000)
    sensor.initialise()
    assert (node.mode, node.cutoff_hz, node.period_us) == ("async", 2.0, 2000)
    first = sensor.read()
    assert sensor.read().counter != first.counter


def test_full_scales_are_read_and_used_in_scaling(
    make_node: NodeFactory, make_sensor: SensorFactory, physics: CellPhysics
) -> None:
    """Unusual full scales from the adapter give the true wrench within half a count."""
    scales = (100.0, 300.0, 500.0, 5.0, 15.0, 25.0)
    physics.tool = TOOL
    physics.set_pose(TILTED)
    make_node(model=Jr3ModelParams(**{**QUIET.__dict__, "full_scales": scales}))
    sensor = make_sensor()
    sensor.initialise()
    assert sensor.full_scales.tolist() == list(scales)
    truth = physics.true_wrench()
    assert np.all(np.abs(truth) > 0.05)
    reading = sensor.read().wrench
    assert np.all(np.abs(reading - truth) <= np.array(scales) / 16384 * 0.51)


@pytest.mark.parametrize(
    "wire",
    [((0, 0, 0), (0, 0, 0)), ((65535,) * 3, (65535,) * 3), ((200, 200, 400), (200, 0, 200))],
)
def test_implausible_full_scales_from_the_adapter_are_refused(
    make_node: NodeFactory,
    make_sensor: SensorFactory,
    monkeypatch: pytest.MonkeyPatch,
    wire: tuple[tuple[int, ...], tuple[int, ...]],
) -> None:
    """Full scales of 0 or 0xFFFF from the wire stop initialisation with SensorError.

    Accepted, a zero full scale reads every wrench as 0 N and no force limit can trip.
    """
    monkeypatch.setattr(firmware_module, "full_scales_to_wire", lambda _fs: wire)
    make_node(model=QUIET)
    sensor = make_sensor()
    with pytest.raises(SensorError, match="implausible"):
        sensor.initialise()
    assert sensor.full_scales is None


@pytest.mark.parametrize(
    "scales", [(0.0,) * 6, (200.0, 200.0, -1.0, 20.0, 20.0, 20.0), (1e9,) * 6,
               (200.0, 200.0, 400.0, 20.0, 20.0, float("nan"))],
)
def test_implausible_configured_full_scales_are_config_errors(scales: tuple[float, ...]) -> None:
    """The same plausibility check guards jr3.full_scales from the configuration."""
    with pytest.raises(ConfigError, match="full_scales"):
        Jr3Config(full_scales=scales)


def test_configured_full_scales_override_the_adapter(
    make_node: NodeFactory, make_sensor: SensorFactory, physics: CellPhysics, channel: str
) -> None:
    """With full scales in the config the driver asks for none and scales with the given ones."""
    physics.tool = TOOL
    make_node(model=QUIET)
    sensor = make_sensor(full_scales=(400.0, 400.0, 800.0, 40.0, 40.0, 40.0))
    ids = _ids(channel, sensor.initialise)
    assert not {0x481, 0x501} & set(ids)
    # the emulator encodes with half these scales, so readings come out doubled
    assert sensor.read().wrench[2] == pytest.approx(2 * physics.true_wrench()[2], abs=0.1)


def test_zero_offsets_brings_the_mean_reading_to_zero_within_noise(
    make_node: NodeFactory, make_sensor: SensorFactory, physics: CellPhysics
) -> None:
    """Tool weight and bias read far from zero before, and within the noise after zeroing."""
    physics.tool = TOOL
    physics.set_pose(TILTED)
    node = make_node(seed=3)
    sensor = make_sensor()
    noise = np.array(node.model.params.noise_std)
    before = np.mean([sensor.read().wrench for _ in range(100)], axis=0)
    assert np.max(np.abs(before[:3]) / noise[:3]) > 10
    sensor.zero_offsets()
    after = np.mean([sensor.read().wrench for _ in range(300)], axis=0)
    print("mean after zeroing / noise std per axis:", np.round(after / noise, 2))
    assert np.all(np.abs(after) < noise)


def test_cutoff_change_is_acknowledged(make_node: NodeFactory, make_sensor: SensorFactory) -> None:
    """set_cutoff returns after the ACK and the adapter uses the new cut-off."""
    node = make_node()
    sensor = make_sensor(cutoff_hz=125.0)
    sensor.initialise()
    sensor.set_cutoff(7.8)
    assert node.cutoff_hz == 7.8 and sensor.cutoff_hz == 7.8
    with pytest.raises(ValueError, match="cutoff_hz"):
        sensor.set_cutoff(1000.0)


def test_sync_stepping_gives_one_sample_per_sync(
    make_node: NodeFactory, make_sensor: SensorFactory
) -> None:
    """Sync stepping gives one sample per sync.

    Each read sends one SYNC; the pair comes at the adapter's next 1 ms loop turn, so the counter
    (sensor frames, 128.5 µs each) steps by 7 or 8 and each sample carries ~1 ms of sensor time.
    (This test used to expect the counter to step by 1 per sample: the old, wrong emulator.)
    """
    node = make_node(initial_counter=100)
    # a SYNC unanswered for a quarter of the stale timeout is sent again (counted): on a loaded
    # host the emulator's thread can sleep 0.1 s (51 SYNCs for 50 samples in a clean-clone CI
    # beside a study); this test is about the stepping, so allow such pauses
    sensor = make_sensor(stale_timeout_s=4.0)
    samples = [sensor.read() for _ in range(50)]
    steps = {(b.counter - a.counter) % 65536 for a, b in itertools.pairwise(samples)}
    assert steps <= {7, 8} and steps
    assert all(s.sensor_dt_s == pytest.approx(((s.counter - p.counter) % 65536) * 128.5e-6)
               for p, s in itertools.pairwise(samples))
    assert node.stats.samples == 50 and node.stats.syncs == 50
    stats = sensor.stats
    assert (stats.samples, stats.dropped_samples, stats.unpaired_frames) == (50, 0, 0)


def test_read_many_sends_one_sync_per_sample_across_the_counter_wrap(
    make_node: NodeFactory, make_sensor: SensorFactory
) -> None:
    """Read many sends one sync per sample across the counter wrap.

    read_many(200, window=4) sends exactly 200 SYNCs (one in flight: the adapter answers one per
    turn), returns 200 samples ~1 ms of sensor time apart, the wrap included.
    """
    node = make_node(initial_counter=65000)
    sensor = make_sensor()
    samples = sensor.read_many(200, window=4)
    counters = [s.counter for s in samples]
    assert any(b < a for a, b in itertools.pairwise(counters))  # it wrapped
    dts = [s.sensor_dt_s for s in samples[1:]]
    assert all(dt is not None and round(dt / 128.5e-6) in (7, 8) for dt in dts)
    assert node.stats.syncs == 200 and node.stats.syncs_merged == 0
    assert node.stats.samples == 200


def test_saturation_is_flagged_near_full_scale(
    make_node: NodeFactory, make_sensor: SensorFactory, physics: CellPhysics
) -> None:
    """A load of 1.7 x full scale on Fz flags Fz only; beyond 2 x the reading clips at int16."""
    physics.tool = ToolParams(mass_kg=1.7 * 400.0 / 9.80665, com_mm=(0.0, 0.0, 0.0))
    make_node(model=QUIET)
    sensor = make_sensor()
    assert sensor.read().saturated == (False, False, True, False, False, False)
    physics.tool = ToolParams(mass_kg=3.0 * 400.0 / 9.80665, com_mm=(0.0, 0.0, 0.0))
    physics.set_pose(Pose(0.0, 0.0, 0.0))
    # the adapter's low-pass follows the new load within a few samples, then the int16 clips
    assert sensor.read_many(10, 10)[-1].wrench[2] == pytest.approx(-32768 * 400.0 / 16384)


@pytest.mark.parametrize("route", ["virtual"])  # spies or breaks the virtual bus itself
def test_no_adapter_raises_sensor_timeout(make_sensor: SensorFactory) -> None:
    """Without an adapter on the bus, initialisation fails with SensorTimeout, a TimeoutError."""
    sensor = make_sensor(ack_timeout_s=0.05)
    t0 = time.monotonic()
    with pytest.raises(SensorTimeout, match="no ACK to get_state") as info:
        sensor.initialise()
    assert isinstance(info.value, TimeoutError)
    assert time.monotonic() - t0 < 1.0


def test_bus_errors_are_converted_with_their_cause(channel: str) -> None:
    """A python-can error while sending becomes SensorBusError raised from it."""
    bus = can.Bus(interface="virtual", channel=channel)
    bus.shutdown()
    sensor = Jr3CanSensor(bus, Jr3Config(ack_timeout_s=0.05))
    with pytest.raises(SensorBusError) as info:
        sensor.initialise()
    assert isinstance(info.value.__cause__, can.CanError)
    sensor.close()


def test_close_sends_stop_is_idempotent_and_final(
    make_node: NodeFactory, make_sensor: SensorFactory
) -> None:
    """Close stops the adapter; a second close is harmless; reading afterwards is an error."""
    node = make_node()
    sensor = make_sensor()
    sensor.read()
    sensor.close()
    sensor.close()
    assert node.mode == "idle"
    with pytest.raises(SensorError, match="closed"):
        sensor.read()


def test_context_manager_initialises_and_closes(make_node: NodeFactory, bus: can.BusABC) -> None:
    """``with`` initialises on entry and stops the adapter on exit."""
    node = make_node()
    with Jr3CanSensor(bus, Jr3Config(ack_timeout_s=0.2)) as sensor:
        assert node.mode == "sync"
        sensor.read()
    assert node.mode == "idle"


@pytest.mark.parametrize("suffix", [".asc", ".log", ".blf"])
def test_traffic_log_uses_python_can_writers(
    make_node: NodeFactory, make_sensor: SensorFactory, tmp_path: Path, suffix: str
) -> None:
    """The log file's writer is chosen by suffix and holds both commands and samples."""
    make_node()
    path = tmp_path / f"traffic{suffix}"
    sensor = make_sensor(log_path=str(path))
    for _ in range(3):
        sensor.read()
    sensor.close()
    ids = {msg.arbitration_id for msg in can.LogReader(path)}
    assert {0x401, 0x181, 0x080, 0x101, 0x601, 0x681, 0x281} <= ids


@pytest.mark.parametrize(
    ("key", "value"),
    [("node_id", 0), ("mode", "both"), ("cutoff_hz", -1.0), ("cutoff_hz", 0.001),
     ("period_us", 0),
     ("full_scales", (1.0, 2.0)), ("stale_timeout_s", 0.0), ("opcodes_version", "1999")],
)
def test_config_errors_name_the_key(key: str, value: object) -> None:
    """A bad configuration value raises ConfigError (a ValueError) naming its key."""
    with pytest.raises(ConfigError, match=key):
        Jr3Config(**{key: value})


def test_reset_restarts_pairing_without_a_bootup(
    make_node: NodeFactory, make_sensor: SensorFactory
) -> None:
    """Reset restarts pairing without a bootup.

    The adapter ACKs a reset with no bootup and counts from 0 again: the driver restarts pairing
    itself, so the first sample after it carries no sensor time from the old count.
    """
    node = make_node()
    sensor = make_sensor()
    for _ in range(30):
        sensor.read()
    sensor.reset()
    sample = sensor.read()
    assert sample.sensor_dt_s is None and sample.counter < 30
    assert sensor.read().sensor_dt_s is not None
    stats = sensor.stats
    assert (stats.bootups, stats.duplicate_samples, stats.dropped_samples) == (0, 0, 0)
    assert node.stats.bootups == 0


def test_cutoff_zero_asks_the_adapter_for_unfiltered_data(
    make_node: NodeFactory, make_sensor: SensorFactory
) -> None:
    """``cutoff_hz = 0`` is sent as 0: the adapter's raw decoupled data."""
    node = make_node()
    sensor = make_sensor(cutoff_hz=0.0)
    sensor.initialise()
    assert (node.mode, node.cutoff_hz, sensor.cutoff_hz) == ("sync", 0.0, 0.0)


def test_default_config_zeroes_on_initialisation(
    make_node: NodeFactory, bus: can.BusABC
) -> None:
    """Default config zeroes on initialisation.

    Jr3Config() zeroes (as the public host driver always does): the adapter's offsets are 0 after
    power-up, so without it the sensor's 1.5..3 N bias would be in every reading.
    """
    node = make_node()
    with Jr3CanSensor(bus, Jr3Config(zero_settle_s=0.0)) as sensor:
        readings = np.array([s.wrench for s in sensor.read_many(50)])
        assert node.model.offset[:3].tolist() != [0.0, 0.0, 0.0]
    assert node.model.offset[:3].tolist() == [0.0, 0.0, 0.0]  # the stop on close lost them
    assert np.abs(readings[:, :3].mean(axis=0)).max() < 0.2


def test_sample_period_is_what_the_adapter_delivers() -> None:
    """Sync: one sample per 1 ms loop turn; async: the streaming period."""
    bus = can.Bus(interface="virtual", channel=f"period-{os.getpid()}")
    try:
        assert Jr3CanSensor(bus, Jr3Config()).sample_period_s == 0.001
        async_sensor = Jr3CanSensor(bus, Jr3Config(mode="async", period_us=2500))
        assert async_sensor.sample_period_s == 0.0025
        async_sensor.close()
    finally:
        bus.shutdown()
