"""Configuration of the EGM driver: where to listen, which egm.proto, timing, bands and limits.

A frozen dataclass validated on construction; the cell config
(:mod:`forcelearn.site.config`) reads the ``[robot]`` table into it with
:func:`forcelearn.config.build`, which names any bad key. The client-side limits are the
computer link's :class:`~forcelearn.drivers.computer_link.config.Limits`, one
definition for both robot drivers.
"""

from __future__ import annotations

import ipaddress
import math
from dataclasses import dataclass, field

from forcelearn.drivers.limits import Limits
from forcelearn.errors import ConfigError
from forcelearn.protocols.egm.codec import VERSIONS, Version

__all__ = ["DEFAULT_PORT", "EgmConfig", "Limits"]

DEFAULT_PORT = 6510
"""ABB's example UDP Unicast Device port (manual 3HAC073318 p.40); abb_libegm uses 6511."""


@dataclass(frozen=True)
class EgmConfig:
    """Everything the EGM driver needs (s, mm, deg, mm/s).

    The PC is the UDP server: the driver binds ``host:port`` (the controller's
    UDP Unicast Device names this address as Remote Address / Remote Port
    Number) and answers only the controller it is paired with:
    ``controller_host`` (and ``controller_port``) when given, otherwise the
    source of the first EgmRobot that starts a session, held for the
    driver's life (docs/egm.md, "Pairing").
    """

    host: str = "127.0.0.1"
    """Address to bind: 127.0.0.1 for the emulator; the PC's cell-network address on site."""
    port: int = DEFAULT_PORT
    """UDP port to bind; 0 lets the OS pick one (tests), read it from ``driver.port``."""
    controller_host: str | None = None
    """The controller's IPv4 address; only its datagrams are used (None: the first valid sender)."""
    controller_port: int | None = None
    """The controller's source UDP port, if fixed (None: pinned from its first valid datagram)."""
    version: Version = "rw7"
    """Which egm.proto the controller speaks: "rw6" (IRC5, RobotWare 6) or "rw7" (OmniCore)."""
    sample_period_s: float = 0.004
    """EGMActPose \\SampleRate (4 ms default, multiples of 4 ms); paces the speed ramp."""
    speed_mm_s: float = 100.0
    """Initial speed of the planned pose toward a target (``set_speed`` changes it)."""
    in_position_mm: float = 0.2
    """Band: in position when feedback and planned are within this of the target (assumption)."""
    in_position_deg: float = 0.1
    """Orientation band of the same test, degrees (assumption)."""
    watchdog_s: float = 0.5
    """Longest wait for the controller's next datagram while the driver expects one."""
    stale_after_s: float = 0.1
    """Real controller only: feedback older than this (25 cycles at 4 ms) is stale."""
    first_message_timeout_s: float = 10.0
    """How long opening waits for the controller's first EgmRobot (start the RAPID program)."""
    lockstep: bool = False
    """Emulated cell only: reply only while a call lets time pass (docs/egm.md, "Lockstep")."""
    limits: Limits = field(default_factory=Limits)

    def __post_init__(self) -> None:
        if not self.host:
            raise ConfigError("robot.host must name an address to bind, e.g. 127.0.0.1")
        if not (isinstance(self.port, int) and 0 <= self.port <= 65535):
            raise ConfigError(f"robot.port must be 0..65535, got {self.port!r}")
        if self.controller_host is not None:
            try:
                if not isinstance(self.controller_host, str):
                    raise TypeError(self.controller_host)
                ipaddress.IPv4Address(self.controller_host)
            except (ipaddress.AddressValueError, TypeError):
                raise ConfigError(
                    f"robot.controller_host must be the controller's IPv4 address, e.g. "
                    f"192.168.125.1, got {self.controller_host!r}"
                ) from None
        if self.controller_port is not None and not (
            isinstance(self.controller_port, int)
            and not isinstance(self.controller_port, bool)
            and 1 <= self.controller_port <= 65535
        ):
            raise ConfigError(
                f"robot.controller_port must be 1..65535, got {self.controller_port!r}"
            )
        if self.controller_port is not None and self.controller_host is None:
            raise ConfigError("robot.controller_port needs robot.controller_host (the address)")
        if self.version not in VERSIONS:
            raise ConfigError(f"robot.version must be one of {VERSIONS}, got {self.version!r}")
        for name in (
            "sample_period_s",
            "speed_mm_s",
            "in_position_mm",
            "in_position_deg",
            "watchdog_s",
            "stale_after_s",
            "first_message_timeout_s",
        ):
            value = getattr(self, name)
            if not (isinstance(value, int | float) and math.isfinite(value) and value > 0):
                raise ConfigError(f"robot.{name} must be a positive number, got {value!r}")
        ticks = self.sample_period_s / 0.004
        if abs(ticks - round(ticks)) > 1e-9:
            raise ConfigError(
                f"robot.sample_period_s must be a multiple of 0.004 s, got {self.sample_period_s}"
            )
        if self.speed_mm_s > self.limits.max_speed_mm_s:
            raise ConfigError(
                f"robot.speed_mm_s = {self.speed_mm_s} exceeds robot.limits.max_speed_mm_s = "
                f"{self.limits.max_speed_mm_s}"
            )
        if not isinstance(self.lockstep, bool):
            raise ConfigError(f"robot.lockstep must be true or false, got {self.lockstep!r}")

    @property
    def max_seqno_ahead(self) -> int:
        """Largest forward seqno jump taken as lost datagrams: one watchdog of cycles.

        A longer gap means the controller was silent past ``watchdog_s``, which
        ends a wait anyway; a datagram that claims more is implausible (a spoof
        or a corrupt header) and ignored, so it cannot hide the real stream.
        """
        return max(1, math.ceil(self.watchdog_s / self.sample_period_s))

