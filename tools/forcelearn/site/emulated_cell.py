"""The emulated cell: the far ends of a robot's and a sensor's wires, of any kinds, on one physics.

One class for both uses:

* ``run`` (``in_process=True``, through :class:`~forcelearn.site.session.CellSession`):
  the emulators answer the drivers of this process on in-process routes (the
  same bytes as a pty and a CAN adapter, without a thread hand-over per
  exchange) and free loopback ports; only the devices the config marks
  emulated are built.
* ``forcelearn emulate`` (``in_process=False``): both devices, reachable from
  another process exactly as on site: ptys for the computer link and the JR3's
  slcan adapter, loopback UDP/TCP for EGM and the Net F/T. :meth:`site_config`
  prints the config that reaches them.

Every device reads one :class:`CellPhysics` with the sponge and the cell's one
:class:`~forcelearn.emulators.clock.SimClock`, built from the config's
``[emulator]`` tables with its ``profile`` applied. Which emulator serves a
kind is the kinds table's business (:mod:`forcelearn.site.kinds`).

Example::

    from forcelearn.site import EmulatedCell, load_cell_config

    with EmulatedCell(load_cell_config(), robot="egm", sensor="netft",
                      in_process=False) as cell:
        print(cell.site_config())
"""

from __future__ import annotations

import contextlib
import copy
import logging
import os
from collections.abc import Callable, Iterator, Mapping
from pathlib import Path
from typing import Any

from forcelearn.emulators.clock import SimClock
from forcelearn.emulators.physics.cell import CellPhysics
from forcelearn.emulators.physics.part_foam import PartFoam
from forcelearn.emulators.physics.sponge import Sponge
from forcelearn.site.config import CellConfig
from forcelearn.site.kinds import (
    DeviceKind,
    FarEnd,
    FarEndOptions,
    RobotKind,
    SensorKind,
    robot_kind,
    sensor_kind,
)

log = logging.getLogger(__name__)

LEGACY_STATE_KEYS = {"computer_link": "link"}
"""Kind -> the key older checkpoints saved its state under (still read on resume)."""


def emulated_physics(config: CellConfig) -> tuple[Sponge | PartFoam, CellPhysics]:
    """The sponge (or a part's foam) and the one physics object every emulator reads.

    The robot starts at its home pose; ``[emulator.part]`` puts a foam-covered part in
    place of the §5 sponge.
    """
    emulator = config.emulator.effective()
    sponge: Sponge | PartFoam = (
        Sponge(emulator.sponge) if emulator.part is None
        else PartFoam(emulator.part, emulator.sponge))
    clock = SimClock(emulator.time_scale)
    return sponge, CellPhysics(sponge, emulator.arm.home, emulator.tool, clock=clock)


class EmulatedCell:
    """The emulators of one cell: a robot and a sensor of any kinds; a context manager.

    Args:
        config: the cell config; its ``[emulator]`` tables shape the cell and its
            device tables the emulated devices (node id, bit rate, RobotWare...).
        seed: seed of the emulated sensor's noise.
        robot: robot kind (default: the config's); ``None`` with ``in_process``
            builds it only if the config marks it emulated.
        sensor: sensor kind (default: the config's), likewise.
        in_process: True for drivers in this process (``run``), False to serve
            another process (``forcelearn emulate``).
        link_dir: if given, stable symlinks (``robot``, ``jr3-slcan``) in this
            folder point at the ptys (whose paths change on every start), so a
            saved site config stays valid; they are removed on close.
        fresh_per_connection: each time a client opens the sensor anew (a new
            client session; the JR3's slcan adapter reports it) the whole cell
            returns to its state at start. Default False: like a real cell, the
            emulator remembers wear.
        routes: kind name -> that kind's own route options (e.g. ``{"egm":
            EgmRoute(port=6510)}``: :class:`~forcelearn.site.egm_kind.EgmRoute`).
    """

    def __init__(
        self,
        config: CellConfig,
        seed: int = 0,
        *,
        robot: str | None = None,
        sensor: str | None = None,
        in_process: bool = False,
        link_dir: Path | None = None,
        fresh_per_connection: bool = False,
        routes: Mapping[str, object] | None = None,
    ) -> None:
        self.config = config
        self.link_dir = link_dir
        self.fresh_per_connection = fresh_per_connection
        self.sessions = 0
        """Client sessions seen (opens of a device that reports them)."""
        options = FarEndOptions(in_process, seed, dict(routes or {}))
        kinds: list[DeviceKind | None] = [
            _pick(robot, config.robot_kind, config.robot_emulated, in_process, robot_kind),
            _pick(sensor, config.sensor_kind, config.sensor_emulated, in_process, sensor_kind),
        ]
        self.sponge, self.physics = emulated_physics(config)
        self.robot: FarEnd | None = None
        """The robot's far end (None: the robot is real)."""
        self.sensor: FarEnd | None = None
        """The sensor's far end (None: the sensor is real)."""
        self.robot_kind: RobotKind | None = None
        self.sensor_kind: SensorKind | None = None
        self._stack = contextlib.ExitStack()
        try:
            for kind in kinds:
                if kind is not None:
                    self._add(kind, options)
            self._initial = self.state_dict() if fresh_per_connection else {}
            if link_dir is not None:
                self._stack.callback(self._remove_links)
                self._make_links()
        except BaseException:
            self._stack.close()
            raise

    def _add(self, kind: DeviceKind, options: FarEndOptions) -> None:
        far_end = kind.far_end(self.config, self.physics, options)
        self._stack.callback(far_end.close)
        far_end.on_session = self._on_session
        if options.in_process:  # served before the next device is built, as on site
            far_end.start()
        if isinstance(kind, RobotKind):
            self.robot, self.robot_kind = far_end, kind
        else:
            assert isinstance(kind, SensorKind)
            self.sensor, self.sensor_kind = far_end, kind

    def far_ends(self) -> Iterator[tuple[DeviceKind, FarEnd]]:
        """(kind, far end) of each emulated device: the robot first."""
        if self.robot is not None and self.robot_kind is not None:
            yield self.robot_kind, self.robot
        if self.sensor is not None and self.sensor_kind is not None:
            yield self.sensor_kind, self.sensor

    # -- state: the whole cell, every device by its kind's name -----------------------------

    def state_dict(self) -> dict[str, Any]:
        """The cell's state: clock, arm, sponge, and each device under its kind's name."""
        state: dict[str, Any] = {"clock": self.physics.clock.state_dict()}
        if self.physics.motion is not None:
            state["motion"] = self.physics.motion.state_dict()
        state["sponge"] = self.sponge.state_dict()
        for kind, far_end in self.far_ends():
            state[kind.name] = far_end.state_dict()
        return copy.deepcopy(state)

    def load_state_dict(self, state: dict[str, Any]) -> None:
        """Restore :meth:`state_dict` (a key it lacks leaves that part as it is)."""
        state = copy.deepcopy(state)
        if "clock" in state:
            self.physics.clock.load_state_dict(state["clock"])
        if self.physics.motion is not None and "motion" in state:
            self.physics.motion.load_state_dict(state["motion"])
            self.physics.set_pose(self.physics.motion.pose)
        if "sponge" in state:
            self.sponge.load_state_dict(state["sponge"])
        for kind, far_end in self.far_ends():
            key = kind.name if kind.name in state else LEGACY_STATE_KEYS.get(kind.name, kind.name)
            if key in state:
                far_end.load_state_dict(state[key])

    def fresh(self) -> None:
        """Return the whole cell to its state at start (``emulate`` only)."""
        self.load_state_dict(self._initial)

    def _on_session(self) -> None:
        self.sessions += 1
        if self.fresh_per_connection:
            self.fresh()
            log.info("client session %d: fresh cell", self.sessions)

    # -- serving another process ------------------------------------------------------------

    def paths(self) -> dict[str, str]:
        """Stable link name -> the path to give a client (the link when ``link_dir`` is set)."""
        paths = {}
        for _, far_end in self.far_ends():
            for name, target in far_end.links().items():
                paths[name] = str(self.link_dir / name) if self.link_dir else target
        return paths

    def _make_links(self) -> None:
        """Point the stable symlinks at the ptys (replacing stale ones atomically)."""
        assert self.link_dir is not None
        self.link_dir.mkdir(parents=True, exist_ok=True)
        for _, far_end in self.far_ends():
            for name, target in far_end.links().items():
                temporary = self.link_dir / f".{name}.{os.getpid()}"
                temporary.unlink(missing_ok=True)
                temporary.symlink_to(target)
                os.replace(temporary, self.link_dir / name)

    def _remove_links(self) -> None:
        assert self.link_dir is not None
        for _, far_end in self.far_ends():
            for name in far_end.links():
                (self.link_dir / name).unlink(missing_ok=True)

    def describe(self) -> list[str]:
        """One line per device: what it is and where to reach it."""
        paths = self.paths()
        return [far_end.describe(paths) for _, far_end in self.far_ends()]

    def summary(self) -> str:
        """What the devices did (for the last line of ``forcelearn emulate``)."""
        return ", ".join(far_end.summary() for _, far_end in self.far_ends())

    def site_config(self) -> str:
        """A TOML site config that reaches these devices as a real cell's are reached."""
        paths = self.paths()
        lines = [
            "# Site config for a running `forcelearn emulate` (devices only: every other",
            "# table takes its default; add [safety], [task]... as for a real cell).",
        ]
        for kind, far_end in self.far_ends():
            lines += [f"[{kind.role}]", *far_end.site_lines(paths), ""]
        return "\n".join(lines[:-1]) + "\n"

    # -- lifecycle ---------------------------------------------------------------------------

    def start(self) -> None:
        """Start serving every device."""
        for _, far_end in self.far_ends():
            far_end.start()
        log.info("emulated cell: %s", "; ".join(self.describe()))

    def close(self) -> None:
        """Stop every emulator thread, release the ptys and ports; safe to call twice."""
        self._stack.close()

    def __enter__(self) -> EmulatedCell:
        self.start()
        return self

    def __exit__(self, *exc_info: object) -> None:
        self.close()


def _pick(
    named: str | None, configured: str, emulated: bool, in_process: bool,
    lookup: Callable[[str], DeviceKind],
) -> DeviceKind | None:
    """The kind to emulate: the one named, else the config's (in process: if it is emulated)."""
    if named is not None:
        return lookup(named)
    if in_process and not emulated:
        return None
    return lookup(configured)
