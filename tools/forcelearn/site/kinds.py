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
config type and ``[robot]``/``[sensor]`` table builder, its ``[emulator.*]``
model table (:attr:`DeviceKind.emulator_table`), whether a config points at
the built-in emulator, how its driver opens (on the real device or on the
emulator), how its emulator starts (:class:`FarEnd`: in this process for
``run``, on ptys and ports for ``forcelearn emulate``) with its own route
options, and saves its state, how ``forcelearn check`` reports on it, and
(robots) how often the driver sees the robot's state (:meth:`RobotKind.polling`,
for the twin). Adding a device is one entry here plus its driver, its emulator
and one such object::

    from forcelearn.site import kinds
    kinds.register(MyGripperSensorKind())   # then [sensor] kind = "my_gripper"

or, from another distribution, an entry point of the group
:data:`ENTRY_POINT_GROUP` (the name is the kind's, the object its kind)::

    [project.entry-points."forcelearn.kinds"]
    kuka_rsi = "forcelearn_kuka.kind:KIND"

Kinds read the cell config through :class:`~forcelearn.site.cell_view.CellView`
(what :class:`~forcelearn.site.config.CellConfig` is; the config module reads
this table, so this one does not import it) and its devices' configs through
:class:`~forcelearn.site.cell_view.RobotConfig` and
:class:`~forcelearn.site.cell_view.SensorConfig` (re-exported here).
"""

from __future__ import annotations

import argparse
import contextlib
import importlib
from abc import ABC, abstractmethod
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from importlib.metadata import EntryPoint, entry_points
from typing import ClassVar, Literal, Protocol, TypeVar

from forcelearn.calibration import SensorInfo
from forcelearn.devices import ForceSensor, Robot
from forcelearn.drivers.limits import Limits
from forcelearn.emulators.physics.arm import ArmConfig
from forcelearn.emulators.physics.cell import CellPhysics
from forcelearn.errors import ConfigError
from forcelearn.site.cell_view import (
    BusView,
    CanBusKwargs,
    CellView,
    EmulatorView,
    RobotConfig,
    SensorConfig,
)

Printer = Callable[[str], None]
"""Where ``forcelearn check`` writes its report lines."""
Role = Literal["robot", "sensor"]
ENTRY_POINT_GROUP = "forcelearn.kinds"
"""Entry-point group through which another distribution adds kinds (name: the kind's)."""
__all__ = [
    "ALIASES", "DEFAULT_ROBOT_KIND", "DEFAULT_SENSOR_KIND", "ENTRY_POINT_GROUP", "ROBOT_KINDS",
    "SENSOR_KINDS", "BusView", "CanBusKwargs", "CellView", "DeviceKind", "EmulatorView",
    "FarEnd", "FarEndOptions", "Polling", "Printer", "RobotConfig", "RobotKind", "Role",
    "SensorConfig", "SensorKind", "Serving", "UnmodelledKind", "installed_entry_points",
    "jsonable", "kind_of", "known", "load_entry_points", "register", "robot_kind",
    "robot_kind_of", "sensor_kind", "sensor_kind_of", "typed_part",
]


class Serving(Protocol):
    """One emulator of a far end (the lifecycle of :mod:`forcelearn.emulators`)."""

    def start(self) -> object:
        """Serve (idempotent)."""
        ...

    def close(self) -> None:
        """Stop and release; safe to call twice."""
        ...


@dataclass(frozen=True)
class FarEndOptions:
    """How an emulated cell's far ends are reached.

    Attributes:
        in_process: True for ``run`` (the drivers are in this process: in-process
            routes, free ports); False for ``forcelearn emulate`` (ptys and the
            devices' usual ports, for another process).
        seed: seed of the sensor noise.
        routes: kind name -> that kind's own route options (EGM's
            :class:`~forcelearn.site.egm_kind.EgmRoute`...); a kind absent takes
            its defaults.
    """

    in_process: bool = True
    seed: int = 0
    routes: Mapping[str, object] = field(default_factory=dict)


class FarEnd:
    """The emulator(s) at the far end of one device's wire, in an emulated cell.

    Subclasses fill :attr:`emulators` (started in order, closed in reverse) and
    :attr:`emulator` (what tests and figures inspect) and override the hooks.
    """

    def __init__(self) -> None:
        self.emulators: list[Serving] = []
        """Everything to start and close (the lifecycle of forcelearn.emulators)."""
        self.emulator: object = None
        """The device's emulator (robot controller, JR3 node, EGM controller, Net F/T box)."""
        self.driver: object = None
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

    def state_dict(self) -> dict[str, object]:
        """What a bit-identical resume of this device needs (JSON-able)."""
        return {}

    def load_state_dict(self, state: dict[str, object]) -> None:
        """Restore :meth:`state_dict`."""

    def links(self) -> dict[str, str]:
        """Stable symlink name -> pty path (``forcelearn emulate --link-dir``)."""
        return {}

    def describe(self, paths: dict[str, str]) -> str:
        """One line for ``forcelearn emulate``: what it is and where to reach it."""
        return f"{type(self).__name__}: {getattr(self.emulator, 'address', '')}"

    def site_lines(self, paths: dict[str, str]) -> list[str]:
        """The table lines of a site config reaching it (``paths``: pty or its stable link)."""
        return []

    def summary(self) -> str:
        """What it did, for ``forcelearn emulate``'s last line."""
        return ""


@dataclass(frozen=True)
class Polling:
    """How a robot driver's polls of a wait are spaced and stamped, from the config (s)."""

    period_s: float
    """One poll (a guess: the twin reads the period from the records)."""
    unanswered_s: float
    """The part of each poll outside stamp-to-answer: the controller stamps a poll when its
    request has arrived, the driver has the answer a reply later, then the next request
    goes (the computer link: the request and the PC's DLE ACK; EGM: the whole period)."""

    def answer_s(self, period_s: float) -> float:
        """From a poll's stamp to the driver holding its answer, for a poll of ``period_s``."""
        return max(0.0, period_s - self.unanswered_s)


class UnmodelledKind(ConfigError):
    """A program (the twin) needs a model of a device kind that the kind does not give."""


class DeviceKind(ABC):
    """What every device kind tells the cell (see the module doc)."""

    role: ClassVar[Role]
    name: str
    """Table key, the ``kind`` value of the config table."""
    label: str
    """Human name ("computer link", "Net F/T")."""
    config_type: type[object]
    """The driver's frozen config dataclass the table builds."""
    emulated_key: str = "host"
    """The key of its config table that ``"emulated"`` goes in for the built-in emulator."""
    emulator_table: str | None = None
    """The ``[emulator.NAME]`` table of its emulator's model (None: it takes none)."""
    model_type: type[object] | None = None
    """The frozen dataclass that table builds (its defaults: the model when absent)."""

    def model(self, emulator: EmulatorView) -> object:
        """This kind's emulator model in ``emulator`` (its default when the table was absent)."""
        found = emulator.devices.get(self.name)
        if found is None and self.model_type is not None:
            found = self.model_type()
        return found

    @abstractmethod
    def describe(self, config: CellView) -> str:
        """The device line of ``forcelearn check``'s header (where it is reached)."""

    @abstractmethod
    def location(self, config: CellView) -> str:
        """The real device for the live page ("computer link /dev/ttyS0", "JR3 on slcan:...")."""

    def missing(self, config: CellView) -> list[str]:
        """One line per serial port of this device that does not exist (``check``)."""
        return []

    @abstractmethod
    def far_end(self, config: CellView, physics: CellPhysics, options: FarEndOptions) -> FarEnd:
        """Build (not yet serving) this device's emulator on the cell's physics."""

    def add_emulate_arguments(self, parser: argparse.ArgumentParser) -> None:
        """Add this kind's route options to ``forcelearn emulate`` (none by default)."""
        return

    def route_from_arguments(self, arguments: argparse.Namespace) -> object | None:
        """This kind's route options from ``forcelearn emulate``'s arguments (None: defaults)."""
        return None


class RobotKind(DeviceKind):
    """A robot kind: ``[robot] kind = name``."""

    role: ClassVar[Role] = "robot"

    @abstractmethod
    def load(self, table: dict[str, object], limits: Limits) -> RobotConfig:
        """Build the config from the ``[robot]`` table (``kind`` removed); limits from [safety]."""

    @abstractmethod
    def emulated(self, robot: RobotConfig) -> bool:
        """True when the config points at the built-in emulator."""

    @abstractmethod
    def open(self, config: CellView, far_end: FarEnd | None, stack: contextlib.ExitStack) -> Robot:
        """Open (and initialise) the driver on the real robot or on ``far_end``.

        Registers its close on ``stack``; errors keep their type and gain a note
        naming what to check.
        """

    @abstractmethod
    def check(self, robot: Robot, say: Printer) -> Callable[[], None]:
        """Report on the open robot without moving it; return the check to run afterwards.

        The returned call raises ``SafetyStop`` if the robot moved meanwhile.
        """

    @abstractmethod
    def calibration_name(self, robot: Robot) -> str:
        """The robot's name as a calibration file records it."""

    def polling(self, robot: RobotConfig, arm: ArmConfig) -> Polling:
        """How often the driver sees the robot's state while it waits (the twin's arm model).

        Raises:
            UnmodelledKind: the kind gives no such model (the default).
        """
        raise UnmodelledKind(
            f"robot kind {self.name!r} gives no polling model: the twin cannot take its "
            f"records; give {type(self).__name__} a polling() to fit its cells"
        )


class SensorKind(DeviceKind):
    """A force/torque sensor kind: ``[sensor] kind = name``."""

    role: ClassVar[Role] = "sensor"
    emulator_table: str | None = "sensor"
    learner_keys: tuple[str, ...] = ()
    """Keys of its ``[sensor]`` table that shape what the learner reads (rate, filter...), as
    opposed to where the device is: an emulated copy of the cell (a twin) keeps them."""

    def take_bus(self, table: dict[str, object]) -> dict[str, object] | None:
        """Pop the CAN bus keys from the ``[sensor]`` table (None: the kind has no CAN bus)."""
        return None

    @abstractmethod
    def load(self, table: dict[str, object]) -> SensorConfig:
        """Build the config from the ``[sensor]`` table (``kind`` and bus keys removed)."""

    @abstractmethod
    def emulated(self, sensor: SensorConfig, bus: BusView) -> bool:
        """True when the config (and the cell's CAN bus) points at the built-in emulator."""

    def filter_defaults(self, sensor: SensorConfig) -> dict[str, object]:
        """``[filter]`` defaults that follow from this sensor (its noise band, its rate)."""
        return {}

    @abstractmethod
    def open(
        self, config: CellView, far_end: FarEnd | None, stack: contextlib.ExitStack
    ) -> ForceSensor:
        """Open (and initialise) the driver on the real sensor or on ``far_end`` (see RobotKind)."""

    @abstractmethod
    def check(self, sensor: ForceSensor, config: CellView, seconds: float, say: Printer) -> None:
        """Read ``seconds`` of samples and report rate, losses, mean and noise per axis."""

    @abstractmethod
    def calibration_info(
        self, config: CellView, sensor: ForceSensor, robot_name: str, model: str | None,
        serial: str,
    ) -> SensorInfo:
        """The ``SensorInfo`` a calibration file records of this sensor."""


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


def installed_entry_points() -> list[EntryPoint]:
    """The entry points of :data:`ENTRY_POINT_GROUP` of every installed distribution."""
    return list(entry_points(group=ENTRY_POINT_GROUP))


def load_entry_points() -> None:
    """Add every installed entry point's kind to its table (a name already there stays)."""
    for point in installed_entry_points():
        if point.name in ROBOT_KINDS or point.name in SENSOR_KINDS:
            continue
        kind = point.load()
        if not isinstance(kind, RobotKind | SensorKind):
            raise TypeError(f"entry point {point.name} = {point.value!r} of group "
                            f"{ENTRY_POINT_GROUP} is not a RobotKind or SensorKind")
        if kind.name != point.name:
            raise TypeError(f"entry point {point.name} = {point.value!r} names a kind "
                            f"called {kind.name!r}")
        register(kind)


def _resolve(entry: tuple[str, str] | DeviceKind) -> DeviceKind:
    if isinstance(entry, DeviceKind):
        return entry
    module, attribute = entry
    kind = getattr(importlib.import_module(module), attribute)
    if not isinstance(kind, DeviceKind):
        raise TypeError(f"{module}.{attribute} is not a DeviceKind")
    return kind


def _entry(role: Role, name: object) -> DeviceKind:
    """The kind called ``name`` in ``role``'s table, else an installed entry point's."""
    table: Mapping[str, tuple[str, str] | DeviceKind] = (
        ROBOT_KINDS if role == "robot" else SENSOR_KINDS)
    if isinstance(name, str) and name not in table:
        load_entry_points()
    entry = table.get(name) if isinstance(name, str) else None
    if entry is None:
        raise ConfigError(f"{role}.kind = {name!r}: one of {list(table)}")
    return _resolve(entry)


def robot_kind(name: str) -> RobotKind:
    """The robot kind called ``name`` (``ConfigError`` naming the known ones)."""
    kind = _entry("robot", ALIASES.get(name, name) if isinstance(name, str) else name)
    if not isinstance(kind, RobotKind):
        raise TypeError(f"ROBOT_KINDS[{name!r}] is a {type(kind).__name__}, not a RobotKind")
    return kind


def sensor_kind(name: str) -> SensorKind:
    """The sensor kind called ``name`` (``ConfigError`` naming the known ones)."""
    kind = _entry("sensor", name)
    if not isinstance(kind, SensorKind):
        raise TypeError(f"SENSOR_KINDS[{name!r}] is a {type(kind).__name__}, not a SensorKind")
    return kind


def robot_kind_of(robot: object) -> RobotKind:
    """The robot kind whose config type ``robot`` is (``ConfigError`` if none is)."""
    for name in list(ROBOT_KINDS):
        kind = robot_kind(name)
        if type(robot) is kind.config_type:
            return kind
    raise ConfigError(f"no robot kind takes a {type(robot).__name__}")


def sensor_kind_of(sensor: object) -> SensorKind:
    """The sensor kind whose config type ``sensor`` is (``ConfigError`` if none is)."""
    for name in list(SENSOR_KINDS):
        kind = sensor_kind(name)
        if type(sensor) is kind.config_type:
            return kind
    raise ConfigError(f"no sensor kind takes a {type(sensor).__name__}")


def kind_of(role: Role, device_config: object) -> DeviceKind:
    """The kind whose config type ``device_config`` is (``ConfigError`` if none is)."""
    return robot_kind_of(device_config) if role == "robot" else sensor_kind_of(device_config)


PartT = TypeVar("PartT")


def typed_part(value: object, cls: type[PartT], key: str, owner: str) -> PartT:
    """``value``, the cell's ``key`` (``[robot]``, ``[emulator.sensor]``...), as ``owner``'s type.

    ``cls`` is that type; every kind's accessor (``egm_of``, ``sensor_model``...) narrows with it.

    Raises:
        ConfigError: ``value`` is not a ``cls``: the kind ``owner`` was asked about a
            cell whose device is of another kind.
    """
    if not isinstance(value, cls):
        raise ConfigError(f"{key} holds a {type(value).__name__}, not the {owner}'s "
                          f"{cls.__name__}: this cell's device is of another kind")
    return value


def known(role: Role) -> list[str]:
    """The names of ``role``'s kinds, installed entry points' included."""
    load_entry_points()
    return list(ROBOT_KINDS if role == "robot" else SENSOR_KINDS)


def register(kind: RobotKind | SensorKind) -> None:
    """Add (or replace) a kind in its table, under ``kind.name``."""
    if isinstance(kind, RobotKind):
        ROBOT_KINDS[kind.name] = kind
    elif isinstance(kind, SensorKind):
        SENSOR_KINDS[kind.name] = kind
    else:
        raise TypeError(f"{kind!r} is neither a RobotKind nor a SensorKind")


def jsonable(state: Mapping[str, object]) -> dict[str, object]:
    """``state`` with numpy arrays and scalars inside nested dicts/lists made plain Python."""
    return {key: _plain(value) for key, value in state.items()}


def _plain(value: object) -> object:
    if isinstance(value, dict):
        return {k: _plain(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_plain(v) for v in value]
    tolist = getattr(value, "tolist", None)
    return tolist() if callable(tolist) else value
