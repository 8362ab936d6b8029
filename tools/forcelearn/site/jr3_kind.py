"""``[sensor] kind = "jr3"``: a JR3 force/torque sensor behind its CAN adapter.

Real: python-can opens ``[sensor] interface``/``channel`` at ``bitrate``
(socketcan, pcan, slcan...). Emulated (``interface = "emulated"``, the
default): the JR3 emulator, in this process under python-can as
``can.Bus(interface="forcelearn-jr3", channel=NAME)`` (answered in the
driver's thread) or, for ``forcelearn emulate``, on a private ``virtual``
bus behind an emulated slcan (LAWICEL) USB-CAN adapter on a pseudo-terminal
that python-can's ``slcan`` interface opens from another process.
``Jr3Route("virtual")`` puts ``run``'s emulator on a python-can ``virtual`` bus
(its own thread), as a real adapter is reached.
"""

from __future__ import annotations

import contextlib
import logging
import time
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any, Literal, cast

import can
import numpy as np
from can.interfaces.slcan import slcanBus

from forcelearn.calibration import SensorInfo
from forcelearn.config import build
from forcelearn.devices import AXES, ForceSensor, WrenchSample
from forcelearn.drivers.jr3_can.config import Jr3Config
from forcelearn.drivers.jr3_can.driver import Jr3CanSensor
from forcelearn.emulators import registry
from forcelearn.emulators.jr3.node import Jr3EmulatorNode
from forcelearn.emulators.jr3.sensor_model import Jr3ModelParams
from forcelearn.emulators.physics.cell import CellPhysics
from forcelearn.emulators.slcan import SlcanAdapterEmulator
from forcelearn.errors import CalibrationError, ForcelearnError, SensorBusError
from forcelearn.protocols.jr3_can.opcodes import CounterMeaning
from forcelearn.site.config import EMULATED
from forcelearn.site.kinds import (
    BusView,
    CellView,
    FarEnd,
    FarEndOptions,
    Printer,
    SensorConfig,
    SensorKind,
    jsonable,
    typed_part,
)

log = logging.getLogger(__name__)

SLCAN_LINK = "jr3-slcan"
"""Name of the stable symlink to the slcan adapter's pty (``forcelearn emulate --link-dir``)."""
BUS_KEYS = ("interface", "channel", "bitrate", "sleep_after_open_s")
"""The ``[sensor]`` keys of the CAN bus (:class:`~forcelearn.site.config.BusConfig`)."""
SLCAN_VERSION_TIMEOUT_S = 2.0
"""Longest wait for the slcan adapter's version answer when opening it (s)."""
UNITS = ("N", "N", "N", "N*m", "N*m", "N*m")
BATCH = 20
"""Samples per read_many call while checking (a 20 ms slice at 1 kHz)."""
JR3_ROUTES = ("in_process", "virtual")


@dataclass(frozen=True)
class Jr3Route:
    """How ``run``'s emulated adapter is reached on its bus (this kind's route option).

    ``"in_process"``: ``can.Bus(interface="forcelearn-jr3")``, whose ``send`` hands
    the frame to the adapter and whose ``recv`` runs its next loop turn in the
    caller's thread; ``"virtual"``: a python-can ``virtual`` bus with the adapter's
    own thread on it, as a real bus is. The same frames and simulated times either
    way (tests/envs/test_surface_routes.py).
    """

    route: Literal["in_process", "virtual"] = "in_process"

    def __post_init__(self) -> None:
        if self.route not in JR3_ROUTES:
            raise ValueError(f"JR3 route must be one of {JR3_ROUTES}, got {self.route!r}")
EMULATE_HINT = (" (for `forcelearn emulate`, name the stable links it prints, which survive "
                "restarts, rather than the /dev/pts paths)")


def private_channel(config: CellView) -> str:
    """A CAN channel name (``virtual`` or ``forcelearn-jr3``) no other cell in this process uses."""
    return registry.new_name(config.bus.channel)


def jr3_of(config: CellView) -> Jr3Config:
    """``[sensor]`` of a JR3 cell (``ConfigError`` for another kind)."""
    return typed_part(config.sensor, Jr3Config, "[sensor]", KIND.label)


def sensor_model(config: CellView) -> Jr3ModelParams:
    """``[emulator.sensor]`` of a JR3 cell, with the profile (ideal: no adapter filter)."""
    model = typed_part(KIND.model(config.emulator), Jr3ModelParams, "[emulator.sensor]",
                       KIND.label)
    return replace(model, emulate_filter=False) if config.emulator.ideal else model


class Jr3FarEnd(FarEnd):
    """The JR3 emulator: in process under python-can (``run``), or behind an slcan pty."""

    def __init__(self, config: CellView, physics: CellPhysics, options: FarEndOptions) -> None:
        super().__init__()
        route = options.routes.get(KIND.name, Jr3Route())
        if not isinstance(route, Jr3Route):
            raise TypeError(f"the JR3 kind's route options are a Jr3Route, not {route!r}")
        self.in_process = options.in_process and route.route == "in_process"
        """The driver's bus is a ``forcelearn-jr3`` one (else ``virtual``, or slcan for
        ``emulate``)."""
        self.channel = private_channel(config)
        sensor = config.sensor if isinstance(config.sensor, Jr3Config) else Jr3Config()
        self.node_id = sensor.node_id
        self.bitrate = config.bus.bitrate
        self.emulator: Jr3EmulatorNode = Jr3EmulatorNode(
            physics,
            channel=self.channel,
            node_id=self.node_id,
            model=sensor_model(config),
            seed=options.seed,
            bitrate=None if config.emulator.ideal else config.bus.bitrate,
            in_process=self.in_process,
        )
        self.emulators = [self.emulator]
        self.adapter: SlcanAdapterEmulator | None = None
        if not options.in_process:
            self.adapter = SlcanAdapterEmulator(channel=self.channel, bus_bitrate=self.bitrate)
            self.emulators.append(self.adapter)
            self.adapter.on_open = self._on_open

    def _on_open(self) -> None:
        if self.on_session is not None:
            self.on_session()

    def state_dict(self) -> dict[str, object]:
        """Noise generator, filter state, bias, offsets, frame counter, bus timeline."""
        return jsonable(self.emulator.state_dict())

    def load_state_dict(self, state: dict[str, Any]) -> None:
        """Restore :meth:`state_dict`."""
        self.emulator.load_state_dict(state)

    def links(self) -> dict[str, str]:
        """The slcan adapter's pty, linked as ``jr3-slcan``."""
        return {SLCAN_LINK: self.adapter.address} if self.adapter is not None else {}

    def describe(self, paths: dict[str, str]) -> str:
        """Where another process reaches the adapter."""
        return (f"JR3 sensor (slcan CAN adapter, pty, node {self.node_id}, "
                f"{self.bitrate} bit/s): {paths[SLCAN_LINK]}")

    def site_lines(self, paths: dict[str, str]) -> list[str]:
        """The ``[sensor]`` table reaching the adapter through python-can's slcan."""
        return [
            'interface = "slcan"',
            f'channel = "{paths[SLCAN_LINK]}"',
            f"bitrate = {self.bitrate}",
            "sleep_after_open_s = 0.0   # the emulated adapter needs no settle time",
            f"node_id = {self.node_id}",
        ]

    def summary(self) -> str:
        """Samples sent and frames taken from the slcan host."""
        frames = self.adapter.model.frames_sent if self.adapter is not None else 0
        return (f"{self.emulator.stats.samples} JR3 samples sent, {frames} frames from the "
                "slcan host")


class Jr3Kind(SensorKind):
    """The JR3 over CAN (see the module doc)."""

    name = "jr3"
    label = "JR3"
    config_type = Jr3Config
    emulated_key = "interface"
    learner_keys = ("mode", "cutoff_hz", "period_us", "full_scales")
    model_type = Jr3ModelParams

    def take_bus(self, table: dict[str, object]) -> dict[str, object]:
        """The CAN bus keys (``interface = "emulated"`` by default)."""
        return {key: table.pop(key) for key in BUS_KEYS if key in table}

    def load(self, table: dict[str, object]) -> Jr3Config:
        """The adapter's keys."""
        return build(Jr3Config, table, "sensor")

    def emulated(self, sensor: SensorConfig, bus: BusView) -> bool:
        """``interface = "emulated"``."""
        return bus.interface == EMULATED

    def filter_defaults(self, sensor: SensorConfig) -> dict[str, object]:
        """The adapter's low-pass colours the noise: the filter's noise band is its cut-off."""
        sensor = cast(Jr3Config, sensor)  # the config this kind loaded
        return {"noise_cutoff_hz": sensor.cutoff_hz}

    def describe(self, config: CellView) -> str:
        """Interface, channel, bit rate and node, or the emulator."""
        bus = config.bus
        if config.sensor_emulated:
            return "built-in JR3 emulator on a virtual CAN bus"
        described = (f"CAN interface {bus.interface}, channel {bus.channel}, {bus.bitrate} "
                     f"bit/s, JR3 node {jr3_of(config).node_id}")
        if bus.interface == "slcan" and bus.sleep_after_open_s is None:
            described += ("\n          (python-can's slcan waits 2 s after every open; set "
                          "[sensor] sleep_after_open_s = 0 if your adapter needs no settle time)")
        return described

    def location(self, config: CellView) -> str:
        """Interface and channel."""
        return f"{self.label} on {config.bus.interface}:{config.bus.channel}"

    def missing(self, config: CellView) -> list[str]:
        """The slcan adapter's serial port, if it is a path that does not exist."""
        channel = config.bus.channel
        if config.bus.interface != "slcan" or "://" in channel or Path(channel).exists():
            return []
        return [f"sensor: slcan adapter port {channel} does not exist; check the channel in "
                "[sensor] and that the USB-CAN adapter is plugged in" + EMULATE_HINT]

    def far_end(
        self, config: CellView, physics: CellPhysics, options: FarEndOptions
    ) -> Jr3FarEnd:
        """The JR3 emulator (and, for ``emulate``, its slcan adapter)."""
        return Jr3FarEnd(config, physics, options)

    def open(
        self, config: CellView, far_end: FarEnd | None, stack: contextlib.ExitStack
    ) -> Jr3CanSensor:
        """The CAN bus (the emulator's or the adapter's), then the JR3 driver, initialised."""
        bus = self._open_bus(config, far_end)
        stack.callback(bus.shutdown)
        if far_end is None and config.bus.interface == "slcan":  # a real slcanBus
            _slcan_barrier(bus, config.bus.channel)
        sensor = Jr3CanSensor(bus, jr3_of(config))
        stack.callback(sensor.close)
        try:
            sensor.initialise()
        except ForcelearnError as exc:  # keeps its type and attributes
            exc.add_note(
                f"check [sensor] node_id ({jr3_of(config).node_id}), the bus bitrate and "
                "that the JR3 adapter is powered"
            )
            raise
        if far_end is not None:
            far_end.driver = sensor
        return sensor

    @staticmethod
    def _open_bus(config: CellView, far_end: FarEnd | None) -> can.BusABC:
        if far_end is not None:
            assert isinstance(far_end, Jr3FarEnd)
            interface = "forcelearn-jr3" if far_end.in_process else "virtual"
            return can.Bus(interface=interface, channel=far_end.channel)
        bus = config.bus
        try:
            return can.Bus(interface=bus.interface, channel=bus.channel, bitrate=bus.bitrate,
                           **bus.can_kwargs())
        except (can.CanError, OSError, ValueError, ImportError) as exc:
            raise SensorBusError(
                f"cannot open CAN interface {bus.interface!r} channel {bus.channel!r} at "
                f"{bus.bitrate} bit/s: {exc}; check the adapter is plugged in, the interface "
                "name and the channel (e.g. socketcan/can0, pcan/PCAN_USBBUS1, "
                "slcan/<serial port>)"
            ) from exc

    def check(self, sensor: ForceSensor, config: CellView, seconds: float,
              say: Printer) -> None:
        """Mode, cut-off, full scales; samples, losses, mean and noise per axis."""
        sensor = cast(Jr3CanSensor, sensor)  # the driver this kind opened
        cfg = jr3_of(config)
        scales = sensor.full_scales
        say(f"  sensor  JR3 node {cfg.node_id} initialised: {cfg.mode} mode, cut-off "
            f"{sensor.cutoff_hz:g} Hz, offsets {'zeroed' if cfg.zero_on_init else 'as stored'}")
        if scales is not None:
            say(f"  sensor  full scales {' '.join(f'{s:g}' for s in scales[:3])} N, "
                f"{' '.join(f'{s:g}' for s in scales[3:])} N*m")
        stats_before = sensor.stats
        samples, elapsed, clock = read_for(sensor, seconds)
        stats = sensor.stats
        wrench = np.array([s.wrench for s in samples])
        mean, noise = wrench.mean(axis=0), wrench.std(axis=0)
        say(f"  sensor  {len(samples)} samples in {elapsed:.2f} s of {clock} time: "
            f"{len(samples) / elapsed:.0f} samples/s; "
            f"dropped {stats.dropped_samples - stats_before.dropped_samples} "
            f"(SYNCs unanswered {stats.unanswered_syncs - stats_before.unanswered_syncs}, "
            f"frames lost {stats.lost_frames - stats_before.lost_frames}, "
            f"unpaired {stats.unpaired_frames - stats_before.unpaired_frames}), "
            f"bootups {stats.bootups - stats_before.bootups}, "
            f"rejected frames {stats.rejected_total - stats_before.rejected_total}")
        say("          axis        mean   noise (std)")
        for name, unit, m, n in zip(AXES, UNITS, mean, noise, strict=True):
            say(f"          {name}  {m:>+10.3f}  {n:>10.3f}  {unit}")
        axis, sign = config.filter.axis, config.filter.sign
        say(f"  sensor  normal force ({'+' if sign > 0 else '-'}{AXES[axis]}, [filter] axis "
            f"{axis}): mean {sign * mean[axis]:+.3f} N, noise {noise[axis]:.3f} N")
        if config.calibration_file is not None:
            state = "found" if config.calibration_file.is_file() else "MISSING"
            say(f"  sensor  calibration file {config.calibration_file}: {state}")

    def calibration_info(self, config: CellView, sensor: ForceSensor, robot_name: str,
                         model: str | None, serial: str) -> SensorInfo:
        """Node, full scales and cut-off as the adapter reports them."""
        sensor = cast(Jr3CanSensor, sensor)  # the driver this kind opened
        if sensor.full_scales is None:  # pragma: no cover
            raise CalibrationError("the JR3 did not report its full scales")
        return SensorInfo(
            model=model if model is not None else (
                "JR3 (forcelearn emulator)" if config.sensor_emulated else ""),
            serial=serial,
            node_id=jr3_of(config).node_id,
            full_scales=tuple(float(v) for v in sensor.full_scales),
            cutoff_hz=sensor.cutoff_hz,
            robot=robot_name,
        )


def read_for(sensor: Jr3CanSensor, seconds: float) -> tuple[list[WrenchSample], float, str]:
    """Read samples for ``seconds`` of the sensor's own time: (samples, seconds, "sensor").

    The adapter's frame counter is the sensor's clock (each sample's ``sensor_dt_s``):
    on site it runs with the wall clock, on an emulated cell with the simulated one, so
    a 60 s check of an emulated sensor reads 60 s worth of samples in a few seconds.
    Samples that do not carry their sensor time (older firmware) are read for
    ``seconds`` of wall time: (samples, seconds, "wall").
    """
    samples: list[WrenchSample] = []
    opcodes = getattr(getattr(sensor, "config", None), "opcodes", None)
    on_sensor_clock = getattr(opcodes, "counter", None) is CounterMeaning.SENSOR_FRAMES
    sensor_s = 0.0
    start = time.monotonic()
    while True:
        batch = sensor.read_many(BATCH)
        samples += batch
        if on_sensor_clock:  # None: the first sample after a (re)start, no time known
            sensor_s += sum(s.sensor_dt_s or 0.0 for s in batch)
            if sensor_s >= seconds:
                return samples, sensor_s, "sensor"
        elif (wall_s := time.monotonic() - start) >= seconds:
            return samples, wall_s, "wall"


def _slcan_barrier(bus: can.BusABC, channel: str) -> None:
    """Wait until the slcan adapter has taken its open commands (a ``V`` round trip).

    python-can writes the adapter's close/bitrate/open lines and returns at
    once; the adapter reads them later. Asking its version and waiting for
    the answer puts the channel's opening before any robot traffic of this
    session, always: an emulated cell that starts afresh on that opening
    (``forcelearn emulate --fresh-per-connection``) then sees one order on
    any host. An adapter that does not answer only costs the wait.
    """
    assert isinstance(bus, slcanBus)  # the caller checked [sensor] interface = "slcan"
    try:
        hardware, software = bus.get_version(SLCAN_VERSION_TIMEOUT_S)
    except can.CanError as exc:  # the JR3's initialisation then names the fault
        log.warning("slcan adapter on %s: version query failed: %s", channel, exc)
        return
    if hardware is None:
        log.warning("slcan adapter on %s did not answer the version query within %.1f s",
                    channel, SLCAN_VERSION_TIMEOUT_S)
    else:
        log.info("slcan adapter on %s: hardware %s, software %s", channel, hardware, software)


KIND = Jr3Kind()
