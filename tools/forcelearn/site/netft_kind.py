"""``[sensor] kind = "netft"``: an ATI Net F/T box over Ethernet (RDT on UDP, calibration).

Real: the driver reads the box's calibration and streams RDT records from
``[sensor] host``. Emulated (``host = "emulated"``): the box emulator serves
RDT, READCALINFO and HTTP on loopback and samples the shared physics on the
cell's clock: on free ports in this process (``run``, the RDT records handed
to the driver in process by default: :class:`NetFtRoute`), or on the box's
usual ports where free for ``forcelearn emulate``.
"""

from __future__ import annotations

import contextlib
import logging
import time
from collections.abc import Callable
from dataclasses import dataclass, replace
from typing import Any, Literal, cast

import numpy as np

from forcelearn.calibration import SensorInfo
from forcelearn.config import build
from forcelearn.devices import AXES, ForceSensor
from forcelearn.drivers.netft import NetFtConfig, NetFtSensor
from forcelearn.emulators.netft.in_process import InProcessRdtSocket
from forcelearn.emulators.netft.sensor_model import NetFtModelParams
from forcelearn.emulators.netft.server import MAX_RDT_RATE_HZ, NetFtEmulator
from forcelearn.emulators.physics.cell import CellPhysics
from forcelearn.errors import ConfigError, ForcelearnError
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

NETFT_RDT_HZ = 7000.0
"""The Net F/T's RDT rate when the config names none (the emulator's default), Hz."""
NETFT_SETTLE_TIMEOUT_S = 5.0
"""On resume, longest wait for the emulated Net F/T to take the driver's requests (s)."""
UNITS = ("N", "N", "N", "N*m", "N*m", "N*m")
BATCH = 64
"""Records per read_many call while checking (one burst request)."""
NETFT_ROUTES = ("in_process", "udp")


@dataclass(frozen=True)
class NetFtRoute:
    """How ``run``'s emulated box hands its RDT records to the driver (this kind's route option).

    ``"in_process"``: the driver's socket-like end of the emulator
    (:mod:`forcelearn.emulators.netft.in_process`: the same bytes, no thread
    hand-over per datagram); ``"udp"``: loopback datagrams, as a real box's.
    The calibration is read over loopback TCP/HTTP either way.
    """

    route: Literal["in_process", "udp"] = "in_process"

    def __post_init__(self) -> None:
        if self.route not in NETFT_ROUTES:
            raise ValueError(f"Net F/T route must be one of {NETFT_ROUTES}, got {self.route!r}")


def netft_of(config: CellView) -> NetFtConfig:
    """``[sensor]`` of a Net F/T cell (``ConfigError`` for another kind)."""
    return typed_part(config.sensor, NetFtConfig, "[sensor]", KIND.label)


def box_model(config: CellView) -> NetFtModelParams:
    """``[emulator.sensor]`` of a Net F/T cell: the emulated box's model."""
    return typed_part(KIND.model(config.emulator), NetFtModelParams, "[emulator.sensor]",
                      KIND.label)


class NetFtFarEnd(FarEnd):
    """The Net F/T box emulator on loopback."""

    def __init__(self, config: CellView, physics: CellPhysics, options: FarEndOptions) -> None:
        super().__init__()
        route = options.routes.get(KIND.name, NetFtRoute())
        if not isinstance(route, NetFtRoute):
            raise TypeError(f"the Net F/T kind's route options are a NetFtRoute, not {route!r}")
        self.in_process = options.in_process and route.route == "in_process"
        """The driver takes the emulator's in-process RDT end (else loopback UDP)."""
        sensor = config.sensor if isinstance(config.sensor, NetFtConfig) else NetFtConfig()
        settings: dict[str, Any] = {"model": box_model(config)}
        if options.in_process:  # free ports; ``emulate`` takes the box's own where free
            settings |= {"rdt_port": 0, "tcp_port": 0}
            if sensor.rdt_rate_hz is not None:
                if sensor.rdt_rate_hz > MAX_RDT_RATE_HZ:
                    raise ConfigError(
                        f"[sensor] sensor.rdt_rate_hz = {sensor.rdt_rate_hz:g}: the emulated "
                        f"box streams at most {MAX_RDT_RATE_HZ:g} records/s"
                    )
                settings["rdt_rate_hz"] = sensor.rdt_rate_hz
        self.emulator: NetFtEmulator = NetFtEmulator(
            physics, physics.clock, seed=options.seed, **settings
        )
        self.emulators = [self.emulator]

    def state_dict(self) -> dict[str, object]:
        """The box's state (bias, noise generator, record counter)."""
        return jsonable(self.emulator.state_dict())

    def load_state_dict(self, state: dict[str, Any]) -> None:
        """Restore :meth:`state_dict` after the driver's requests took effect."""
        if isinstance(self.driver, NetFtSensor):
            # What the driver sent while initialising (set bias needs no answer) takes
            # effect before the checkpoint's state, never after it.
            sent = self.driver.stats.requests
            if not self.emulator.wait_handled(sent, NETFT_SETTLE_TIMEOUT_S):
                log.warning("the Net F/T emulator did not handle the driver's %d request(s) "
                            "within %.1f s; the resumed run may differ", sent,
                            NETFT_SETTLE_TIMEOUT_S)
        self.emulator.load_state_dict(state)
        if isinstance(self.driver, NetFtSensor):  # the clock jumped with the restore
            self.driver.restart_uptime_check()

    def zero_in_order(self, driver: NetFtSensor) -> None:
        """Make the driver's "set software bias" take effect before it returns.

        The request needs no answer, and the emulator's thread handles it when
        it gets to it: on a loaded host the robot may have turned by then (the
        host goes on at once), and the box zeroes another load (a tare that
        passed or failed with the host's load). Waiting here puts the bias
        where the host sent it, on the cell's one clock; a real box applies it
        on receipt, so only the emulated cell needs this. The zero of
        ``initialise`` (``zero_on_init``) is waited for here.
        """
        send = driver.zero_offsets

        def taken() -> None:
            if not self.emulator.wait_handled(driver.stats.requests, NETFT_SETTLE_TIMEOUT_S):
                log.warning("the Net F/T emulator did not take the set-bias request within "
                            "%.1f s; the zero may be of a later load", NETFT_SETTLE_TIMEOUT_S)

        def zero_offsets() -> None:
            send()
            taken()

        taken()
        driver.zero_offsets = zero_offsets  # type: ignore[method-assign]

    def describe(self, paths: dict[str, str]) -> str:
        """The box's ports."""
        ports = self.emulator.ports
        return (f"Net F/T sensor (127.0.0.1): RDT UDP {ports['rdt_port']}, READCALINFO TCP "
                f"{ports['tcp_port']}, HTTP {ports['http_port']}")

    def site_lines(self, paths: dict[str, str]) -> list[str]:
        """The ``[sensor]`` table reaching the box."""
        ports = self.emulator.ports
        return [
            'kind = "netft"',
            f'host = "{self.emulator.host}"',
            f"rdt_port = {ports['rdt_port']}",
            f"tcp_port = {ports['tcp_port']}",
            f"http_port = {ports['http_port']}",
            "uptime_check = false  # the emulator's samples follow its own clock, not wall time",
        ]

    def summary(self) -> str:
        """Records sent."""
        return f"{self.emulator.stats.records_sent} Net F/T records sent"


def _clock_of(emulator: NetFtEmulator) -> Callable[[], float]:
    """The emulated box's clock, s: the cell's simulated one (its samples follow it)."""
    sim = emulator.clock

    def now_s() -> float:
        return sim.now_s

    return now_s


class NetFtKind(SensorKind):
    """The Net F/T (see the module doc)."""

    name = "netft"
    label = "Net F/T"
    config_type = NetFtConfig
    learner_keys = ("rdt_rate_hz",)
    model_type = NetFtModelParams

    def load(self, table: dict[str, object]) -> NetFtConfig:
        """The box's keys; ``host`` defaults to the emulator."""
        return build(NetFtConfig, {"host": EMULATED, **table}, "sensor")

    def emulated(self, sensor: SensorConfig, bus: BusView) -> bool:
        """``host = "emulated"``."""
        return isinstance(sensor, NetFtConfig) and sensor.host == EMULATED

    def filter_defaults(self, sensor: SensorConfig) -> dict[str, object]:
        """White noise (no adapter filter); one sample per RDT record."""
        sensor = cast(NetFtConfig, sensor)  # the config this kind loaded
        return {"noise_cutoff_hz": 0.0,
                "sample_period_s": 1.0 / (sensor.rdt_rate_hz or NETFT_RDT_HZ)}

    def describe(self, config: CellView) -> str:
        """The box's address, or the emulator."""
        if config.sensor_emulated:
            return "built-in Net F/T emulator on loopback (RDT UDP, READCALINFO TCP, HTTP)"
        s = netft_of(config)
        return (f"Net F/T at {s.host}: RDT UDP {s.rdt_port}, calibration over "
                f"{s.calibration_source}")

    def location(self, config: CellView) -> str:
        """The box's address."""
        return f"{self.label} at {netft_of(config).host}"

    def far_end(
        self, config: CellView, physics: CellPhysics, options: FarEndOptions
    ) -> NetFtFarEnd:
        """The box emulator (serving from construction)."""
        return NetFtFarEnd(config, physics, options)

    def open(
        self, config: CellView, far_end: FarEnd | None, stack: contextlib.ExitStack
    ) -> NetFtSensor:
        """The driver on the box (or its emulator's ports), initialised."""
        sensor = netft_of(config)
        clock: Callable[[], float] | None = None
        rdt: InProcessRdtSocket | None = None
        if far_end is not None:
            assert isinstance(far_end, NetFtFarEnd)
            ports = far_end.emulator.ports
            sensor = replace(sensor, host=far_end.emulator.host, rdt_port=ports["rdt_port"],
                             tcp_port=ports["tcp_port"], http_port=ports["http_port"])
            clock = _clock_of(far_end.emulator)
            if far_end.in_process:
                rdt = InProcessRdtSocket(far_end.emulator)
        elif sensor.uptime_check:  # a real box counts its samples in wall time
            clock = time.monotonic
        driver = NetFtSensor(sensor, clock=clock, sock=rdt)
        stack.callback(driver.close)
        try:
            driver.initialise()
        except ForcelearnError as exc:  # keeps its type and fields (SensorFault...)
            exc.add_note(
                f"check [sensor] host ({netft_of(config).host}), that the box is powered and "
                "on this subnet, and its calibration (docs/netft.md, On site)"
            )
            raise
        if far_end is not None:
            far_end.driver = driver
            far_end.zero_in_order(driver)
        return driver

    def check(self, sensor: ForceSensor, config: CellView, seconds: float,
              say: Printer) -> None:
        """The box's calibration, a few seconds of records and the counts of faults."""
        sensor = cast(NetFtSensor, sensor)  # the driver this kind opened
        cal = sensor.calibration
        if cal is not None:
            rate = f"{cal.rdt_rate_hz:g} Hz" if cal.rdt_rate_hz else "not reported (TCP)"
            filt = cal.filter_index if cal.filter_index is not None else "not reported"
            say(f"  sensor  Net F/T at {sensor.config.host}: calibration over {cal.source}: "
                f"{cal.counts_per_force:g} counts/{cal.force_unit}, {cal.counts_per_torque:g} "
                f"counts/{cal.torque_unit}; RDT rate {rate}; filter {filt}")
            if cal.ranges_si is not None:
                say(f"  sensor  ranges {' '.join(f'{r:g}' for r in cal.ranges_si[:3])} N, "
                    f"{' '.join(f'{r:g}' for r in cal.ranges_si[3:])} N*m")
        before = sensor.stats
        samples = []
        start = time.monotonic()
        while time.monotonic() - start < seconds:
            samples += sensor.read_many(BATCH)
        elapsed = time.monotonic() - start
        stats = sensor.stats
        rate_note = ""
        if cal is not None and cal.rdt_rate_hz:
            rate_note = f" (the box streams at up to {cal.rdt_rate_hz:g}/s)"
        say(f"  sensor  {len(samples)} records in {elapsed:.2f} s: "
            f"{len(samples) / elapsed:.0f} records/s{rate_note}; lost "
            f"{stats.lost - before.lost}, duplicates {stats.duplicates - before.duplicates}, "
            f"out of order {stats.out_of_order - before.out_of_order}, rejected "
            f"{stats.rejected_total - before.rejected_total}, reboots "
            f"{stats.reboots - before.reboots}")
        wrench = np.array([s.wrench for s in samples])
        mean, noise = wrench.mean(axis=0), wrench.std(axis=0)
        say("          axis        mean   noise (std)")
        for name, unit, m, n in zip(AXES, UNITS, mean, noise, strict=True):
            say(f"          {name}  {m:>+10.3f}  {n:>10.3f}  {unit}")
        axis, sign = config.filter.axis, config.filter.sign
        say(f"  sensor  normal force ({'+' if sign > 0 else '-'}{AXES[axis]}, [filter] axis "
            f"{axis}): mean {sign * mean[axis]:+.3f} N, noise {noise[axis]:.3f} N")

    def calibration_info(self, config: CellView, sensor: ForceSensor, robot_name: str,
                         model: str | None, serial: str) -> SensorInfo:
        """Ranges and RDT rate as the box reports them."""
        sensor = cast(NetFtSensor, sensor)  # the driver this kind opened
        cal = sensor.calibration
        scales = netft_of(config).full_scales or (cal.ranges_si if cal is not None else None)
        return SensorInfo(
            model=model if model is not None else (
                "ATI Net F/T (forcelearn emulator)" if config.sensor_emulated
                else "ATI Net F/T"),
            serial=serial,
            full_scales=tuple(float(v) for v in scales) if scales else (0.0,) * 6,
            # the box filters by index (setuserfilter), not by a cut-off: the recorded
            # noise's bandwidth is the RDT stream's Nyquist frequency
            cutoff_hz=0.5 * (
                (cal.rdt_rate_hz if cal is not None else None)
                or netft_of(config).rdt_rate_hz
                or NETFT_RDT_HZ
            ),
            robot=robot_name,
        )


KIND = NetFtKind()
