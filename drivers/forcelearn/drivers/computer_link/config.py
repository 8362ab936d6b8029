"""Configuration of the computer-link driver: port, timing, retries and client-side limits.

Frozen dataclasses, validated on construction (the cell config,
:mod:`forcelearn.site.config`, reads the ``[robot]`` table into them).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import serial

from forcelearn.drivers.limits import Limits as Limits  # re-exported: its old home
from forcelearn.errors import ConfigError

POLL_S = 0.01
"""Read slice of the serial port (s); timeouts are kept to within about this."""


@dataclass(frozen=True)
class LinkConfig:
    """Everything the driver needs to reach one controller.

    Timing (s) and retry counts are the protocol's (docs/computer-link.md).
    """

    url: str
    """Port for ``serial.serial_for_url``: /dev/ttyS0, COM3, a pty path, socket://127.0.0.1:P."""
    baudrate: int = 9600
    bytesize: int = serial.EIGHTBITS
    parity: str = serial.PARITY_NONE
    stopbits: float = serial.STOPBITS_ONE
    ack_timeout_s: float = 1.0
    """Wait for DLE ACK after sending a request before sending DLE ENQ."""
    reply_timeout_s: float = 1.0
    """Wait for the reply frame after DLE ACK before sending DLE ENQ."""
    nak_retries: int = 3
    """Retransmissions of a request (after DLE NAK or a lost request), and DLE NAKs we send."""
    enq_retries: int = 3
    """DLE ENQs per transaction before giving up with LinkTimeout."""
    limits: Limits = field(default_factory=Limits)

    def __post_init__(self) -> None:
        if not self.url:
            raise ConfigError("url must name a port, e.g. /dev/ttyS0 or socket://127.0.0.1:5001")
        if self.baudrate <= 0:
            raise ConfigError(f"baudrate must be positive, got {self.baudrate}")
        if self.parity not in serial.PARITY_NAMES:
            raise ConfigError(f"parity must be one of {sorted(serial.PARITY_NAMES)}")
        if self.bytesize not in serial.Serial.BYTESIZES:
            raise ConfigError(f"bytesize must be one of {list(serial.Serial.BYTESIZES)} bits, "
                              f"got {self.bytesize!r}")
        if self.stopbits not in serial.Serial.STOPBITS:
            raise ConfigError(f"stopbits must be one of {list(serial.Serial.STOPBITS)}, "
                              f"got {self.stopbits!r}")
        for name in ("ack_timeout_s", "reply_timeout_s"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0):
                raise ConfigError(f"{name} must be a positive number of seconds, got {value!r}")
        for name in ("nak_retries", "enq_retries"):
            if not 0 <= getattr(self, name) <= 10:
                raise ConfigError(f"{name} must be 0..10, got {getattr(self, name)!r}")
