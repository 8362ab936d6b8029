"""What a device kind reads of a cell: the cell config and its devices' configs, as Protocols.

:class:`~forcelearn.site.config.CellConfig` is a :class:`CellView`; each
robot kind's config a :class:`RobotConfig`, each sensor kind's a
:class:`SensorConfig`. The kinds (:mod:`forcelearn.site.kinds`) are typed by
these, so they need not import the config module, which reads their table.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Protocol, TypedDict

from forcelearn.drivers.limits import Limits
from forcelearn.emulators.physics.arm import ArmConfig
from forcelearn.filtering import ForceFilterConfig


class RobotConfig(Protocol):
    """What every robot kind's config carries: the driver's limits (from ``[safety]``)."""

    @property
    def limits(self) -> Limits:
        """Workspace, step and speed the driver enforces before a command leaves the PC."""
        ...


class SensorConfig(Protocol):
    """What every sensor kind's config carries (``[safety]`` and the zeroing rule set them)."""

    @property
    def stale_timeout_s(self) -> float:
        """No sample within this time raises ``SensorStale``, s."""
        ...

    @property
    def zero_on_init(self) -> bool:
        """Zero the sensor's offsets when it opens (tool in free space)."""
        ...


class CanBusKwargs(TypedDict, total=False):
    """Extra keyword arguments of ``can.Bus`` that a ``[sensor]`` table may set."""

    sleep_after_open: float
    """python-can's slcan wait after opening the adapter, s."""


class BusView(Protocol):
    """The cell's CAN bus as a kind reads it (:class:`~forcelearn.site.config.BusConfig`)."""

    @property
    def interface(self) -> str: ...  # noqa: D102 - the fields of BusConfig
    @property
    def channel(self) -> str: ...  # noqa: D102
    @property
    def bitrate(self) -> int: ...  # noqa: D102
    @property
    def sleep_after_open_s(self) -> float | None: ...  # noqa: D102

    def can_kwargs(self) -> CanBusKwargs:
        """Extra keyword arguments for ``can.Bus``."""
        ...


class EmulatorView(Protocol):
    """The ``[emulator]`` tables as a kind reads them (``site.config.EmulatorConfig``)."""

    @property
    def arm(self) -> ArmConfig:
        """The emulated arm every robot kind moves."""
        ...

    @property
    def ideal(self) -> bool:
        """True for the zero-time profile."""
        ...

    @property
    def devices(self) -> Mapping[str, object]:
        """Kind name -> the model its ``[emulator.*]`` table built (absent: the kind's default)."""
        ...

    def effective(self) -> EmulatorView:
        """The models with the profile applied."""
        ...


class CellView(Protocol):
    """What a kind reads of the cell config (:class:`~forcelearn.site.config.CellConfig`)."""

    @property
    def robot(self) -> RobotConfig: ...  # noqa: D102 - the fields of CellConfig
    @property
    def sensor(self) -> SensorConfig: ...  # noqa: D102
    @property
    def bus(self) -> BusView: ...  # noqa: D102
    @property
    def emulator(self) -> EmulatorView: ...  # noqa: D102
    @property
    def filter(self) -> ForceFilterConfig: ...  # noqa: D102
    @property
    def calibration_file(self) -> Path | None: ...  # noqa: D102
    @property
    def robot_emulated(self) -> bool: ...  # noqa: D102
    @property
    def sensor_emulated(self) -> bool: ...  # noqa: D102
