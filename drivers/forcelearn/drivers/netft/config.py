"""Configuration of the Net F/T driver: one frozen dataclass, validated at construction."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Literal

from forcelearn.errors import ConfigError
from forcelearn.protocols import netft as protocol

SECTION = "sensor"
"""The TOML table the cell config gives this driver (``[sensor]`` with ``kind = "netft"``)."""


@dataclass(frozen=True)
class NetFtConfig:
    """How the driver talks to one ATI Net F/T box.

    Attributes:
        host: the box's IP address (factory default 192.168.1.1).
        rdt_port: UDP port of the RDT interface (49152).
        calibration_source: ``"http"`` (``/netftapi2.xml``; also tells the RDT
            rate, filter and ranges) or ``"tcp"`` (READCALINFO on ``tcp_port``).
        tcp_port: READCALINFO port (49151).
        http_port: web server port (80).
        counts_per_force, counts_per_torque: optional expected values; if set,
            the box must report the same or the driver refuses, naming both.
        force_unit, torque_unit: optional expected units (``"N"``, ``"N-m"``...).
        rdt_rate_hz: optional expected RDT output rate (checked when the source
            is HTTP, which reports it).
        mode: ``"burst"`` (each ``read_many`` asks for exactly the records it
            needs: start streaming with a sample count) or ``"stream"``
            (infinite streaming; ``read`` returns the newest record).
        burst_records: most records asked for in one request (UDP receive
            buffers overflow beyond a few hundred).
        stale_timeout_s: no record within this time raises ``SensorStale``.
        connect_timeout_s: timeout of the TCP/HTTP calibration exchange.
        near_saturation_fraction: |value| at or above this fraction of the
            calibrated range (``full_scales``, or ``cfgmr`` over HTTP) flags the axis.
        full_scales: optional six ranges (N, N, N, N·m, N·m, N·m) for the
            saturation flag; None takes the box's ``cfgmr`` if it reports one.
        status_error_mask: status bits that raise ``SensorFault`` (the manual:
            a healthy box sends 0; any set bit needs attention).
        zero_on_init: send "set software bias" at initialisation (tool in free space!).
        uptime_check: the cell passes the host's clock to the driver, which then sees a
            reboot whose sample count did not go back (:mod:`.uptime`); off only for
            a box that does not follow wall time (an emulator in another process).
        log_path: optional traffic log of every datagram (:mod:`.traffic_log`).
    """

    host: str = "192.168.1.1"
    rdt_port: int = protocol.RDT_PORT
    calibration_source: Literal["http", "tcp"] = "http"
    tcp_port: int = protocol.CALIBRATION_TCP_PORT
    http_port: int = protocol.HTTP_PORT
    counts_per_force: float | None = None
    counts_per_torque: float | None = None
    force_unit: str | None = None
    torque_unit: str | None = None
    rdt_rate_hz: float | None = None
    mode: Literal["burst", "stream"] = "burst"
    burst_records: int = 64
    stale_timeout_s: float = 0.1
    connect_timeout_s: float = 1.0
    near_saturation_fraction: float = 0.95
    full_scales: tuple[float, float, float, float, float, float] | None = None
    status_error_mask: int = 0xFFFFFFFF
    zero_on_init: bool = False
    uptime_check: bool = True
    log_path: str | None = None

    def __post_init__(self) -> None:
        if not isinstance(self.host, str) or not self.host:
            raise ConfigError(f"{SECTION}.host={self.host!r}: the box's IP address or name")
        for key in ("rdt_port", "tcp_port", "http_port"):
            value = getattr(self, key)
            if not isinstance(value, int) or not 0 <= value <= 0xFFFF:
                raise ConfigError(f"{SECTION}.{key}={value!r}: must be a port 0..65535")
        if self.calibration_source not in ("http", "tcp"):
            raise ConfigError(
                f"{SECTION}.calibration_source={self.calibration_source!r}: 'http' or 'tcp'"
            )
        for key in ("counts_per_force", "counts_per_torque", "rdt_rate_hz"):
            value = getattr(self, key)
            if value is not None and not (
                isinstance(value, int | float) and math.isfinite(value) and value > 0
            ):
                raise ConfigError(f"{SECTION}.{key}={value!r}: must be a positive number")
        if self.force_unit is not None and self.force_unit not in protocol.FORCE_UNIT_SI:
            raise ConfigError(f"{SECTION}.force_unit={self.force_unit!r}: known "
                              f"{sorted(protocol.FORCE_UNIT_SI)}")
        if self.torque_unit is not None and self.torque_unit not in protocol.TORQUE_UNIT_SI:
            raise ConfigError(f"{SECTION}.torque_unit={self.torque_unit!r}: known "
                              f"{sorted(protocol.TORQUE_UNIT_SI)}")
        if self.mode not in ("burst", "stream"):
            raise ConfigError(f"{SECTION}.mode={self.mode!r}: 'burst' or 'stream'")
        if not isinstance(self.burst_records, int) or not 1 <= self.burst_records <= 1024:
            raise ConfigError(f"{SECTION}.burst_records={self.burst_records!r}: must be 1..1024")
        for key in ("stale_timeout_s", "connect_timeout_s"):
            value = getattr(self, key)
            if not (isinstance(value, int | float) and math.isfinite(value) and value > 0):
                raise ConfigError(f"{SECTION}.{key}={value!r}: must be a positive number of s")
        if not 0 < self.near_saturation_fraction <= 1:
            raise ConfigError(f"{SECTION}.near_saturation_fraction="
                              f"{self.near_saturation_fraction!r}: must be in (0, 1]")
        if self.full_scales is not None and (
            len(self.full_scales) != 6 or not all(v > 0 for v in self.full_scales)
        ):
            raise ConfigError(f"{SECTION}.full_scales: six positive values (N x3, N*m x3)")
        if not isinstance(self.status_error_mask, int) or not (
            0 <= self.status_error_mask <= 0xFFFFFFFF
        ):
            raise ConfigError(f"{SECTION}.status_error_mask: a u32 bit mask")

