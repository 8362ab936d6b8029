"""The emulated cell as a stand-alone device pair: a robot link pty and an slcan adapter pty.

What ``forcelearn emulate`` runs. Unlike :class:`~forcelearn.site.session.CellSession`
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
import copy
import logging
import os
from pathlib import Path
from typing import Any, Literal

from forcelearn.emulators import registry
from forcelearn.emulators.clock import SimClock, serial_char_time_s
from forcelearn.emulators.jr3.node import Jr3EmulatorNode
from forcelearn.emulators.physics.cell import CellPhysics
from forcelearn.emulators.physics.sponge import Sponge
from forcelearn.emulators.physics.tool import ToolParams
from forcelearn.emulators.robot_controller.server import RobotControllerEmulator
from forcelearn.emulators.slcan import SlcanAdapterEmulator
from forcelearn.site.config import CellConfig

log = logging.getLogger(__name__)

ROBOT_LINK = "robot"
SLCAN_LINK = "jr3-slcan"
"""Names of the stable symlinks in ``link_dir``."""


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
    robot = config.link
    return serial_char_time_s(robot.baudrate, robot.bytesize, robot.parity, robot.stopbits)


def emulated_robot(
    config: CellConfig, physics: CellPhysics, transport: Literal["pty", "inproc"] = "pty"
) -> RobotControllerEmulator:
    """The robot-controller emulator on a pty or in-process (not yet serving: ``start()``)."""
    return RobotControllerEmulator(
        transport,
        config=config.emulator.effective().arm,
        physics=physics,
        char_time_s=link_char_time_s(config),
    )


def private_channel(config: CellConfig) -> str:
    """A CAN channel name (``virtual`` or ``forcelearn-jr3``) no other cell in this process uses."""
    return registry.new_name(config.bus.channel)


def emulated_jr3(
    config: CellConfig, physics: CellPhysics, channel: str, seed: int, in_process: bool = False
) -> Jr3EmulatorNode:
    """The JR3 adapter emulator on the ``virtual`` CAN ``channel`` (or in-process under it)."""
    return Jr3EmulatorNode(
        physics,
        channel=channel,
        node_id=config.jr3.node_id,
        model=config.emulator.effective().sensor,
        seed=seed,
        bitrate=None if config.emulator.ideal else config.bus.bitrate,
        in_process=in_process,
    )


class EmulatedCell:
    """Robot controller + JR3 behind an slcan adapter, one physics; a context manager.

    Args:
        config: the cell config; its ``[emulator]`` tables, ``sensor.node_id``
            and ``[sensor] bitrate`` shape the emulated devices.
        seed: seed of the emulated sensor's noise.
        link_dir: if given, stable symlinks ``robot`` and ``jr3-slcan`` in this
            folder point at the ptys (whose paths change on every start), so a
            saved site config stays valid; they are removed on stop.
        fresh_per_connection: each time a client opens the CAN adapter (a new
            client session) the sponge and the sensor return to their state at
            start. Default False: like a real cell, the emulator remembers wear.
    """

    def __init__(
        self,
        config: CellConfig,
        seed: int = 0,
        link_dir: Path | None = None,
        fresh_per_connection: bool = False,
    ) -> None:
        self.config = config
        self.link_dir = link_dir
        self.sessions = 0
        """Client sessions seen (opens of the CAN adapter)."""
        self.sponge, self.physics = emulated_physics(config)
        self._stack = contextlib.ExitStack()
        try:
            self.robot = emulated_robot(config, self.physics)
            self._stack.callback(self.robot.close)
            channel = private_channel(config)
            self.sensor = emulated_jr3(config, self.physics, channel, seed)
            self._stack.callback(self.sensor.close)
            self.adapter = SlcanAdapterEmulator(channel=channel, bus_bitrate=config.bus.bitrate)
            self._stack.callback(self.adapter.close)
            self._initial = self._state()
            self.fresh_per_connection = fresh_per_connection
            self.adapter.on_open = self._on_session
            if link_dir is not None:
                self._stack.callback(self._remove_links)
                self._make_links()
        except BaseException:
            self._stack.close()
            raise

    @property
    def robot_path(self) -> str:
        """The robot link's serial port (the stable symlink when ``link_dir`` is set)."""
        return str(self.link_dir / ROBOT_LINK) if self.link_dir else self.robot.address

    @property
    def slcan_path(self) -> str:
        """The slcan adapter's serial port (the stable symlink when ``link_dir`` is set)."""
        return str(self.link_dir / SLCAN_LINK) if self.link_dir else self.adapter.address

    def _state(self) -> dict[str, Any]:
        """The whole emulated cell's state: clock, arm, link wires, sponge, sensor."""
        assert self.physics.motion is not None
        return copy.deepcopy({
            "clock": self.physics.clock.state_dict(),
            "motion": self.physics.motion.state_dict(),
            "link": self.robot.engine.state_dict(),
            "sponge": self.sponge.state_dict(),
            "jr3": self.sensor.state_dict(),
        })

    def fresh(self) -> None:
        """Return the whole cell to its state at start: clock, arm at home, sponge, sensor."""
        state = copy.deepcopy(self._initial)
        assert self.physics.motion is not None
        self.physics.clock.load_state_dict(state["clock"])
        self.physics.motion.load_state_dict(state["motion"])
        self.physics.set_pose(self.physics.motion.pose)
        self.robot.engine.load_state_dict(state["link"])
        self.sponge.load_state_dict(state["sponge"])
        self.sensor.load_state_dict(state["jr3"])

    def _on_session(self) -> None:
        self.sessions += 1
        if self.fresh_per_connection:
            self.fresh()
            log.info("client session %d: fresh cell", self.sessions)

    def _make_links(self) -> None:
        """Point the stable symlinks at the ptys (replacing stale ones atomically)."""
        assert self.link_dir is not None
        self.link_dir.mkdir(parents=True, exist_ok=True)
        for name, target in ((ROBOT_LINK, self.robot.address), (SLCAN_LINK, self.adapter.address)):
            temporary = self.link_dir / f".{name}.{os.getpid()}"
            temporary.unlink(missing_ok=True)
            temporary.symlink_to(target)
            os.replace(temporary, self.link_dir / name)

    def _remove_links(self) -> None:
        assert self.link_dir is not None
        for name in (ROBOT_LINK, SLCAN_LINK):
            (self.link_dir / name).unlink(missing_ok=True)

    def start(self) -> None:
        """Start serving both ports."""
        self.robot.start()
        self.adapter.start()
        log.info("emulated cell: robot on %s, slcan on %s", self.robot_path, self.slcan_path)

    def close(self) -> None:
        """Stop every emulator thread and release the ptys; safe to call twice."""
        self._stack.close()

    def __enter__(self) -> EmulatedCell:
        self.start()
        return self

    def __exit__(self, *exc_info: object) -> None:
        self.close()

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
            "sleep_after_open_s = 0.0   # the emulated adapter needs no settle time\n"
            f"node_id = {self.config.jr3.node_id}\n"
        )
