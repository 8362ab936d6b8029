"""The one table of device kinds: every robot and force sensor a cell can hold.

What ``can.interfaces.BACKENDS`` is to python-can: a name (``[robot] kind``,
``[sensor] kind``, ``forcelearn emulate --robot/--sensor``) maps to the module
and object that know that device, imported only when a cell uses it:

=================  ==========  ===========================  ============================
kind               role        config type                  module
=================  ==========  ===========================  ============================
``computer_link``  robot       ``LinkConfig`` (serial)      :mod:`.computer_link_kind`
``egm``            robot       ``EgmConfig`` (UDP)          :mod:`.egm_kind`
``jr3``            sensor      ``Jr3Config`` + CAN bus      :mod:`.jr3_kind`
``netft``          sensor      ``NetFtConfig`` (Ethernet)   :mod:`.netft_kind`
=================  ==========  ===========================  ============================

Each entry is a :class:`RobotKind` or :class:`SensorKind`: its label, its
config type and ``[robot]``/``[sensor]`` table builder, whether a config
points at the built-in emulator, how its driver opens (on the real device or
on the emulator), how its emulator starts (:class:`FarEnd`: in this process for
``run``, on ptys and ports for ``forcelearn emulate``) and saves its state, and
how ``forcelearn check`` reports on it. Adding a device is one entry here plus
its driver, its emulator and one such object::

    from forcelearn.site import kinds
    kinds.register(MyGripperSensorKind())   # then [sensor] kind = "my_gripper"

Kind objects receive the cell config (a
:class:`~forcelearn.site.config.CellConfig`, typed :data:`AnyCellConfig` here
because the config module reads this table).
"""

from __future__ import annotations

import contextlib
import importlib
from abc import ABC, abstractmethod
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, ClassVar, Literal

from forcelearn.drivers.limits import Limits
from forcelearn.emulators.physics.cell import CellPhysics
from forcelearn.errors import ConfigError

AnyCellConfig = Any
"""A :class:`forcelearn.site.config.CellConfig` (not imported: that module imports this one)."""
Printer = Callable[[str], None]
"""Where ``forcelearn check`` writes its report lines."""
Role = Literal["robot", "sensor"]

ROBOT_KINDS: dict[str, tuple[str, str] | RobotKind] = {
    "computer_link": ("forcelearn.site.computer_link_kind", "KIND"),
    "egm": ("forcelearn.site.egm_kind", "KIND"),
}
"""``[robot] kind`` -> (module, attribute) of its :class:`RobotKind`, or the object itself."""
SENSOR_KINDS: dict[str, tuple[str, str] | SensorKind] = {
    "jr3": ("forcelearn.site.jr3_kind", "KIND"),
    "netft": ("forcelearn.site.netft_kind", "KIND"),
}
"""``[sensor] kind`` -> (module, attribute) of its :class:`SensorKind`, or the object itself."""
DEFAULT_ROBOT_KIND = "computer_link"
DEFAULT_SENSOR_KIND = "jr3"
ALIASES: dict[str, str] = {"link": "computer_link"}
"""Deprecated spellings still accepted on the command line (``emulate --robot link``)."""


@dataclass(frozen=True)
class FarEndOptions:
    """How an emulated cell's far ends are reached.

    Attributes:
        in_process: True for ``run`` (the drivers are in this process: in-process
            routes, free ports); False for ``forcelearn emulate`` (ptys and the
            devices' usual ports, for another process).
        seed: seed of the sensor noise.
        egm_route: in-process EGM only: ``"in_process"`` or ``"udp"`` (loopback).
        egm_port: ``forcelearn emulate`` only: the PC's UDP port EGM sends to (0: free).
    """

    in_process: bool = True
    seed: int = 0
    egm_route: str = "in_process"
    egm_port: int = 0


class FarEnd:
    """The emulator(s) at the far end of one device's wire, in an emulated cell.

    Subclasses fill :attr:`emulators` (started in order, closed in reverse) and
    :attr:`emulator` (what tests and figures inspect) and override the hooks.
    """

    def __init__(self) -> None:
        self.emulators: list[Any] = []
        """Everything to start and close (the lifecycle of forcelearn.emulators)."""
        self.emulator: Any = None
        """The device's emulator (robot controller, JR3 node, EGM controller, Net F/T box)."""
        self.driver: Any = None
        """The in-process driver talking to it, once the session opened one."""
        self.on_session: Callable[[], None] | None = None
        """Called when a client opens the device anew (``--fresh-per-connection``)."""

    def start(self) -> None:
        """Serve (idempotent; emulators that serve from construction are started already)."""
        for emulator in self.emulators:
            emulator.start()

    def close(self) -> None:
        """Stop and release the emulators (reverse order); safe to call twice."""
        with contextlib.ExitStack() as stack:
            for emulator in self.emulators:
                stack.callback(emulator.close)

    def state_dict(self) -> dict[str, Any]:
        """What a bit-identical resume of this device needs (JSON-able)."""
        return {}

    def load_state_dict(self, state: dict[str, Any]) -> None:
        """Restore :meth:`state_dict`."""

    def links(self) -> dict[str, str]:
        """Stable symlink name -> pty path (``forcelearn emulate --link-dir``)."""
        return {}

    def describe(self, paths: dict[str, str]) -> str:
        """One line for ``forcelearn emulate``: what it is and where to reach it."""
        return f"{type(self).__name__}: {self.emulator.address}"

    def site_lines(self, paths: dict[str, str]) -> list[str]:
        """The table lines of a site config reaching it (``paths``: pty or its stable link)."""
        return []

    def summary(self) -> str:
        """What it did, for ``forcelearn emulate``'s last line."""
        return ""


class DeviceKind(ABC):
    """What every device kind tells the cell (see the module doc)."""

    role: ClassVar[Role]
    name: str
    """Table key, the ``kind`` value of the config table."""
    label: str
    """Human name ("computer link", "Net F/T")."""
    config_type: type[Any]
    """The driver's frozen config dataclass the table builds."""
    emulated_key: str = "host"
    """The key of its config table that ``"emulated"`` goes in for the built-in emulator."""

    def device_config_or_default(self, config: AnyCellConfig) -> Any:
        """The cell's config of this device, or the kind's defaults if the cell has another."""
        device = getattr(config, self.role)
        return device if isinstance(device, self.config_type) else self.config_type()

    @abstractmethod
    def describe(self, config: AnyCellConfig) -> str:
        """The device line of ``forcelearn check``'s header (where it is reached)."""

    @abstractmethod
    def location(self, config: AnyCellConfig) -> str:
        """The real device for the live page ("computer link /dev/ttyS0", "JR3 on slcan:...")."""

    def missing(self, config: AnyCellConfig) -> list[str]:
        """One line per serial port of this device that does not exist (``check``)."""
        return []

    @abstractmethod
    def far_end(
        self, config: AnyCellConfig, physics: CellPhysics, options: FarEndOptions
    ) -> FarEnd:
        """Build (not yet serving) this device's emulator on the cell's physics."""

    @abstractmethod
    def open(
        self, config: AnyCellConfig, far_end: FarEnd | None, stack: contextlib.ExitStack
    ) -> Any:
        """Open (and initialise) the driver on the real device or on ``far_end``.

        Registers its close on ``stack``; errors keep their type and gain a note
        naming what to check.
        """


class RobotKind(DeviceKind):
    """A robot kind: ``[robot] kind = name``."""

    role: ClassVar[Role] = "robot"

    @abstractmethod
    def load(self, table: dict[str, Any], limits: Limits) -> Any:
        """Build the config from the ``[robot]`` table (``kind`` removed); limits from [safety]."""

    @abstractmethod
    def emulated(self, robot: Any) -> bool:
        """True when the config points at the built-in emulator."""

    @abstractmethod
    def check(self, robot: Any, say: Printer) -> Callable[[], None]:
        """Report on the open robot without moving it; return the check to run afterwards.

        The returned call raises ``SafetyStop`` if the robot moved meanwhile.
        """

    @abstractmethod
    def calibration_name(self, robot: Any) -> str:
        """The robot's name as a calibration file records it."""


class SensorKind(DeviceKind):
    """A force/torque sensor kind: ``[sensor] kind = name``."""

    role: ClassVar[Role] = "sensor"
    model_field: str | None = None
    """The :class:`~forcelearn.site.config.EmulatorConfig` field that ``[emulator.sensor]``
    fills for this kind (None: the kind's emulator takes no model table)."""
    model_type: type[Any] | None = None
    """The type of that field."""
    learner_keys: tuple[str, ...] = ()
    """Keys of its ``[sensor]`` table that shape what the learner reads (rate, filter...), as
    opposed to where the device is: an emulated copy of the cell (a twin) keeps them."""

    def take_bus(self, table: dict[str, Any]) -> dict[str, Any] | None:
        """Pop the CAN bus keys from the ``[sensor]`` table (None: the kind has no CAN bus)."""
        return None

    @abstractmethod
    def load(self, table: dict[str, Any]) -> Any:
        """Build the config from the ``[sensor]`` table (``kind`` and bus keys removed)."""

    @abstractmethod
    def emulated(self, sensor: Any, bus: Any) -> bool:
        """True when the config (and the cell's CAN bus) points at the built-in emulator."""

    def filter_defaults(self, sensor: Any) -> dict[str, Any]:
        """``[filter]`` defaults that follow from this sensor (its noise band, its rate)."""
        return {}

    @abstractmethod
    def check(self, sensor: Any, config: AnyCellConfig, seconds: float, say: Printer) -> None:
        """Read ``seconds`` of samples and report rate, losses, mean and noise per axis."""

    @abstractmethod
    def calibration_info(
        self, config: AnyCellConfig, sensor: Any, robot_name: str, model: str | None,
        serial: str,
    ) -> Any:
        """The ``SensorInfo`` a calibration file records of this sensor."""


def _resolve(entry: tuple[str, str] | DeviceKind) -> DeviceKind:
    if isinstance(entry, DeviceKind):
        return entry
    module, attribute = entry
    kind = getattr(importlib.import_module(module), attribute)
    if not isinstance(kind, DeviceKind):
        raise TypeError(f"{module}.{attribute} is not a DeviceKind")
    return kind


def robot_kind(name: str) -> RobotKind:
    """The robot kind called ``name`` (``ConfigError`` naming the known ones)."""
    entry = ROBOT_KINDS.get(ALIASES.get(name, name)) if isinstance(name, str) else None
    if entry is None:
        raise ConfigError(f"robot.kind = {name!r}: one of {list(ROBOT_KINDS)}")
    kind = _resolve(entry)
    if not isinstance(kind, RobotKind):
        raise TypeError(f"ROBOT_KINDS[{name!r}] is a {type(kind).__name__}, not a RobotKind")
    return kind


def sensor_kind(name: str) -> SensorKind:
    """The sensor kind called ``name`` (``ConfigError`` naming the known ones)."""
    entry = SENSOR_KINDS.get(name) if isinstance(name, str) else None
    if entry is None:
        raise ConfigError(f"sensor.kind = {name!r}: one of {list(SENSOR_KINDS)}")
    kind = _resolve(entry)
    if not isinstance(kind, SensorKind):
        raise TypeError(f"SENSOR_KINDS[{name!r}] is a {type(kind).__name__}, not a SensorKind")
    return kind


def kind_of(role: Role, device_config: object) -> DeviceKind:
    """The kind whose config type ``device_config`` is (``ConfigError`` if none is)."""
    table = ROBOT_KINDS if role == "robot" else SENSOR_KINDS
    lookup = robot_kind if role == "robot" else sensor_kind
    for name in table:
        kind = lookup(name)
        if type(device_config) is kind.config_type:
            return kind
    raise ConfigError(f"no {role} kind takes a {type(device_config).__name__}")


def register(kind: RobotKind | SensorKind) -> None:
    """Add (or replace) a kind in its table, under ``kind.name``."""
    if isinstance(kind, RobotKind):
        ROBOT_KINDS[kind.name] = kind
    elif isinstance(kind, SensorKind):
        SENSOR_KINDS[kind.name] = kind
    else:
        raise TypeError(f"{kind!r} is neither a RobotKind nor a SensorKind")


def jsonable(value: Any) -> Any:
    """Turn numpy arrays and scalars inside nested dicts/lists into plain Python values."""
    if isinstance(value, dict):
        return {k: jsonable(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [jsonable(v) for v in value]
    if hasattr(value, "tolist"):
        return value.tolist()
    return value
