"""The emulated cell as a stand-alone device pair: a robot link pty and an slcan adapter pty.

What ``forcelearn emulate`` runs. Unlike :class:`~forcelearn.tools.cell_session.CellSession`
(which also opens the drivers, in the same process), this starts only the far
end of the wires, so another process connects exactly as on site:

* the robot-controller emulator on a pseudo-terminal (pyserial opens its path);
* the JR3 emulator on a private ``virtual`` CAN bus, behind an emulated slcan
  (LAWICEL) USB-CAN adapter on a second pseudo-terminal (python-can's
  ``slcan`` interface opens its path).

Both read one :class:`CellPhysics` with the sponge and the cell's one
:class:`~forcelearn.emulators.clock.SimClock`, built from the config's
``[emulator]`` tables (with its ``profile`` applied) as the in-process emulated
cell builds it. The robot's serial line costs the time of the ``[robot]``
settings (baud rate and framing), the CAN bus that of ``[sensor] bitrate``.
"""

from __future__ import annotations

import contextlib
import logging
import uuid

from forcelearn.emulators.clock import SimClock, serial_char_time_s
from forcelearn.emulators.jr3.node import Jr3EmulatorNode
from forcelearn.emulators.physics.cell import CellPhysics
from forcelearn.emulators.physics.sponge import Sponge
from forcelearn.emulators.physics.tool import ToolParams
from forcelearn.emulators.robot_controller.server import RobotControllerEmulator
from forcelearn.emulators.slcan import SlcanAdapterEmulator
from forcelearn.tools.cell_config import CellConfig

log = logging.getLogger(__name__)


def emulated_physics(config: CellConfig) -> tuple[Sponge, CellPhysics]:
    """The sponge and the one physics object both emulators read (robot at its home pose)."""
    emulator = config.emulator.effective()
    sponge = Sponge(emulator.sponge)
    clock = SimClock(emulator.time_scale)
    return sponge, CellPhysics(sponge, emulator.arm.home, ToolParams(), clock=clock)


def link_char_time_s(config: CellConfig) -> float:
    """Seconds per character of the emulated robot link (0 in the ideal profile)."""
    if config.emulator.ideal:
        return 0.0
    robot = config.robot
    return serial_char_time_s(robot.baudrate, robot.bytesize, robot.parity, robot.stopbits)


def emulated_robot(config: CellConfig, physics: CellPhysics) -> RobotControllerEmulator:
    """The robot-controller emulator on a pty (not yet serving: call ``start()``)."""
    return RobotControllerEmulator(
        "pty",
        config=config.emulator.effective().arm,
        physics=physics,
        char_time_s=link_char_time_s(config),
    )


def private_channel(config: CellConfig) -> str:
    """A ``virtual`` CAN channel name no other cell in this process uses."""
    return f"{config.bus.channel}-{uuid.uuid4().hex[:8]}"


def emulated_jr3(
    config: CellConfig, physics: CellPhysics, channel: str, seed: int
) -> Jr3EmulatorNode:
    """The JR3 adapter emulator on the ``virtual`` CAN ``channel``."""
    return Jr3EmulatorNode(
        physics,
        channel=channel,
        node_id=config.sensor.node_id,
        model=config.emulator.effective().sensor,
        seed=seed,
        bitrate=None if config.emulator.ideal else config.bus.bitrate,
    )


class EmulatedCell:
    """Robot controller + JR3 behind an slcan adapter, one physics; a context manager.

    Args:
        config: the cell config; its ``[emulator]`` tables, ``sensor.node_id``
            and ``[sensor] bitrate`` shape the emulated devices.
        seed: seed of the emulated sensor's noise.
    """

    def __init__(self, config: CellConfig, seed: int = 0) -> None:
        self.config = config
        self.sponge, self.physics = emulated_physics(config)
        self._stack = contextlib.ExitStack()
        try:
            self.robot = emulated_robot(config, self.physics)
            self._stack.callback(self.robot.stop)
            channel = private_channel(config)
            self.sensor = emulated_jr3(config, self.physics, channel, seed)
            self._stack.callback(self.sensor.close)
            self.adapter = SlcanAdapterEmulator(channel=channel, bus_bitrate=config.bus.bitrate)
            self._stack.callback(self.adapter.stop)
        except BaseException:
            self._stack.close()
            raise

    @property
    def robot_path(self) -> str:
        """The robot link's serial port (a pty path)."""
        return self.robot.url

    @property
    def slcan_path(self) -> str:
        """The slcan adapter's serial port (a pty path)."""
        return self.adapter.path

    def start(self) -> None:
        """Start serving both ports."""
        self.robot.start()
        self.adapter.start()
        log.info("emulated cell: robot on %s, slcan on %s", self.robot_path, self.slcan_path)

    def stop(self) -> None:
        """Stop every emulator thread and release the ptys; safe to call twice."""
        self._stack.close()

    def __enter__(self) -> EmulatedCell:
        self.start()
        return self

    def __exit__(self, *exc_info: object) -> None:
        self.stop()

    def site_config(self) -> str:
        """A TOML site config that reaches this cell through the pty and python-can's slcan."""
        bus = self.config.bus
        return (
            "# Site config for a running `forcelearn emulate` (devices only: every other\n"
            "# table takes its default; add [safety], [task]... as for a real cell).\n"
            "[robot]\n"
            f'url = "{self.robot_path}"\n'
            "\n"
            "[sensor]\n"
            'interface = "slcan"\n'
            f'channel = "{self.slcan_path}"\n'
            f"bitrate = {bus.bitrate}\n"
            f"node_id = {self.config.sensor.node_id}\n"
        )
