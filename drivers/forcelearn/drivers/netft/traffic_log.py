"""A traffic log of the RDT exchange: every datagram sent and received, raw, with host times.

The counterpart of the JR3 driver's CAN log. One line per datagram::

    # forcelearn netft traffic log v1: host_monotonic_s direction hex
    12.345678 tx 123400020000000a
    12.345912 rx 00000001000003e8000000000000...

``tx`` is host -> box, ``rx`` box -> host; times are ``time.monotonic()`` at
send or receive. Read it back with :func:`read_traffic_log` and decode the
bytes with :mod:`.protocol`.
"""

from __future__ import annotations

import os
import threading
from collections.abc import Iterator
from dataclasses import dataclass
from typing import TextIO

HEADER = "# forcelearn netft traffic log v1: host_monotonic_s direction hex\n"


@dataclass(frozen=True, slots=True)
class LoggedDatagram:
    """One logged datagram: host time (s), ``"tx"`` or ``"rx"``, raw bytes."""

    time_s: float
    direction: str
    data: bytes


class TrafficLog:
    """Append datagrams to a text file; thread-safe; :meth:`close` is idempotent."""

    def __init__(self, path: str | os.PathLike[str]) -> None:
        self.path = os.fspath(path)
        self._lock = threading.Lock()
        self._file: TextIO | None = open(self.path, "w", encoding="ascii")  # noqa: SIM115
        self._file.write(HEADER)

    def write(self, direction: str, data: bytes, time_s: float) -> None:
        """Log one datagram sent (``"tx"``) or received (``"rx"``) at host time ``time_s``."""
        with self._lock:
            if self._file is not None:
                self._file.write(f"{time_s:.6f} {direction} {data.hex()}\n")

    def close(self) -> None:
        """Flush and close the file; safe to call twice."""
        with self._lock:
            if self._file is not None:
                self._file.close()
                self._file = None


def read_traffic_log(path: str | os.PathLike[str]) -> Iterator[LoggedDatagram]:
    """Yield the datagrams of a log written by :class:`TrafficLog`, in order."""
    with open(path, encoding="ascii") as handle:
        for line in handle:
            if line.startswith("#") or not line.strip():
                continue
            time_s, direction, hexdata = line.split()
            yield LoggedDatagram(float(time_s), direction, bytes.fromhex(hexdata))
