"""Emulated cells with Ethernet devices, as their own process: EGM robot and/or Net F/T sensor.

What ``forcelearn emulate --robot egm`` / ``--sensor netft`` runs (the computer
link + JR3 pair is :class:`~forcelearn.site.emulated_cell.EmulatedCell`).
Only the far ends of the wires start here, on one :class:`CellPhysics` and
the cell's one :class:`~forcelearn.emulators.clock.SimClock`:

=================  ============================================================
device             far end
=================  ============================================================
computer link      the robot-controller emulator on a pty
EGM                the EGM controller emulator on 127.0.0.1 UDP, sending to the
                   PC's ``port`` (the site config's ``[robot] port``), in
                   lockstep on the cell's clock; it drives the cell's shared arm
JR3                the JR3 emulator behind an emulated slcan adapter on a pty
Net F/T            the box emulator: RDT on UDP 49152 and READCALINFO on TCP
                   49151 where free (else any free port), HTTP on a free port
=================  ============================================================

The EGM emulator repeats its waiting cycle until a driver answers
(:data:`~forcelearn.emulators.egm.server.RESEND_S`), so the PC side may start
later, and one client may follow another (``check``, then ``run``).
"""

from __future__ import annotations

import contextlib
import logging
import socket
from typing import Any

from forcelearn.drivers.egm import EgmConfig
from forcelearn.emulators.egm import (
    EgmControllerConfig,
    EgmControllerEmulator,
    PhysicsMotion,
)
from forcelearn.emulators.netft.server import NetFtEmulator
from forcelearn.emulators.slcan import SlcanAdapterEmulator
from forcelearn.site.config import CellConfig
from forcelearn.site.emulated_cell import (
    emulated_jr3,
    emulated_physics,
    emulated_robot,
    private_channel,
)
from forcelearn.site.ethernet import egm_arm

log = logging.getLogger(__name__)

ROBOTS = ("link", "egm")
SENSORS = ("jr3", "netft")


def free_udp_port() -> int:
    """A UDP port on 127.0.0.1 free right now (for the PC side of EGM)."""
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as probe:
        probe.bind(("127.0.0.1", 0))
        return int(probe.getsockname()[1])


class EmulatedDevices:
    """One emulated cell's devices of the chosen kinds; a context manager.

    Args:
        config: the cell config (its ``[emulator]`` tables shape the cell).
        seed: seed of the sensor noise.
        robot: ``"link"`` or ``"egm"``.
        sensor: ``"jr3"`` or ``"netft"``.
        egm_port: the PC's UDP port the EGM emulator sends to (0: a free one).
    """

    def __init__(
        self, config: CellConfig, seed: int = 0, robot: str = "link", sensor: str = "jr3",
        egm_port: int = 0,
    ) -> None:
        if robot not in ROBOTS or sensor not in SENSORS:
            raise ValueError(f"robot one of {ROBOTS}, sensor one of {SENSORS}")
        self.config = config
        self.robot_kind, self.sensor_kind = robot, sensor
        self.sponge, self.physics = emulated_physics(config)
        self.link: Any = None
        self.egm: EgmControllerEmulator | None = None
        self.jr3: Any = None
        self.adapter: SlcanAdapterEmulator | None = None
        self.netft: NetFtEmulator | None = None
        self.egm_version = config.robot.version if isinstance(config.robot, EgmConfig) else "rw7"
        self.egm_port = egm_port or free_udp_port()
        self._stack = contextlib.ExitStack()
        try:
            if robot == "link":
                self.link = emulated_robot(config, self.physics)
                self._stack.callback(self.link.close)
            else:
                self._build_egm()
            if sensor == "jr3":
                channel = private_channel(config)
                self.jr3 = emulated_jr3(config, self.physics, channel, seed)
                self._stack.callback(self.jr3.close)
                self.adapter = SlcanAdapterEmulator(
                    channel=channel, bus_bitrate=config.bus.bitrate
                )
                self._stack.callback(self.adapter.close)
            else:
                self.netft = NetFtEmulator(
                    self.physics, self.physics.clock, model=config.emulator.netft, seed=seed
                )
                self._stack.callback(self.netft.close)
        except BaseException:
            self._stack.close()
            raise

    def _build_egm(self) -> None:
        egm_arm(self.config, self.physics)
        arm = self.config.emulator.effective().arm
        self.egm = EgmControllerEmulator(
            self.egm_port,
            physics=self.physics,
            clock=self.physics.clock,
            config=EgmControllerConfig(
                version=self.egm_version,
                servo=self.config.emulator.egm,
                workspace_min_mm=arm.workspace_min_mm,
                workspace_max_mm=arm.workspace_max_mm,
                max_speed_mm_s=arm.max_speed_mm_s,
            ),
            motion=PhysicsMotion(self.physics),
            lockstep=True,
        )
        self._stack.callback(self.egm.close)

    def start(self) -> None:
        """Start serving every device."""
        if self.link is not None:
            self.link.start()
        if self.egm is not None:
            self.egm.start()
        if self.adapter is not None:
            self.adapter.start()

    def close(self) -> None:
        """Stop every emulator; safe to call twice."""
        self._stack.close()

    def __enter__(self) -> EmulatedDevices:
        self.start()
        return self

    def __exit__(self, *exc_info: object) -> None:
        self.close()

    def describe(self) -> list[str]:
        """One line per device: what it is and where to reach it."""
        lines = []
        if self.link is not None:
            lines.append(f"robot link (computer link, pty): {self.link.address}")
        if self.egm is not None:
            lines.append(
                f"robot EGM ({self.egm_version}, UDP from 127.0.0.1:{self.egm.port} to the PC "
                f"at 127.0.0.1:{self.egm_port}, lockstep)"
            )
        if self.adapter is not None:
            lines.append(
                f"JR3 sensor (slcan CAN adapter, pty, node {self.config.jr3.node_id}, "
                f"{self.config.bus.bitrate} bit/s): {self.adapter.address}"
            )
        if self.netft is not None:
            ports = self.netft.ports
            lines.append(
                f"Net F/T sensor (127.0.0.1): RDT UDP {ports['rdt_port']}, READCALINFO TCP "
                f"{ports['tcp_port']}, HTTP {ports['http_port']}"
            )
        return lines

    def summary(self) -> str:
        """What the devices did (for the last line of ``forcelearn emulate``)."""
        parts = []
        if self.link is not None:
            parts.append(f"{self.link.move_count} robot moves executed")
        if self.egm is not None:
            parts.append(f"{self.egm.cycles} EGM cycles, {self.egm.model.targets_read} "
                         "planned poses read")
        if self.jr3 is not None and self.adapter is not None:
            parts.append(f"{self.jr3.stats.samples} JR3 samples sent, "
                         f"{self.adapter.model.frames_sent} frames from the slcan host")
        if self.netft is not None:
            parts.append(f"{self.netft.stats.records_sent} Net F/T records sent")
        return ", ".join(parts)

    def site_config(self) -> str:
        """A TOML site config that reaches these devices as a real cell's are reached."""
        lines = [
            "# Site config for a running `forcelearn emulate` (devices only: every other",
            "# table takes its default; add [safety], [task]... as for a real cell).",
            "[robot]",
        ]
        if self.link is not None:
            lines.append(f'url = "{self.link.address}"')
        else:
            lines += [
                'kind = "egm"',
                'host = "127.0.0.1"',
                f"port = {self.egm_port}",
                f'version = "{self.egm_version}"',
                "lockstep = true       # the emulator keeps step with the driver (one clock)",
                "watchdog_s = 5.0",
            ]
        lines += ["", "[sensor]"]
        if self.adapter is not None:
            lines += [
                'interface = "slcan"',
                f'channel = "{self.adapter.address}"',
                f"bitrate = {self.config.bus.bitrate}",
                f"node_id = {self.config.jr3.node_id}",
            ]
        if self.netft is not None:
            ports = self.netft.ports
            lines += [
                'kind = "netft"',
                f'host = "{self.netft.host}"',
                f"rdt_port = {ports['rdt_port']}",
                f"tcp_port = {ports['tcp_port']}",
                f"http_port = {ports['http_port']}",
            ]
        return "\n".join(lines) + "\n"
