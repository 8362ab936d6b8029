"""Simulated time of an emulated cell: one clock, advanced by traffic and waits, never by the host.

Every emulator of one cell shares a :class:`SimClock`. A device that answers
the host computes *when* (in simulated seconds) each part of the exchange
happens, from what the hardware would spend: bytes on a serial line at its
baud rate (:func:`serial_char_time_s`), CAN frames at their bitrate
(:func:`can_frame_time_s`), the sensor's sample period, the robot's motion.
It then moves the clock to the end of the exchange with :meth:`SimClock.advance_to`.

The clock is "the host's time": the latest moment the host has waited for.
The host is sequential (it sends a request and waits for the answer), so the
order of exchanges, and therefore every simulated time, is fixed by the
traffic alone. The host's wall clock is never read for results: the same
seed and config give the same numbers on an idle or a loaded machine.

Bytes the host sends without waiting for an answer (the computer link's
trailing DLE ACK) occupy their own :class:`Wire` from a time fixed by the
traffic (the end of the reply they acknowledge), not from the clock, so a
thread that happens to process them late changes nothing.

Pace
----
``time_scale = 0`` (default): as fast as the host can go, simulated time only.
``time_scale = 1``: :meth:`SimClock.hold` holds each answer until wall time has
caught up with simulated time, so a session runs at the real cell's pace (for
rehearsal on site); any factor between. Results are identical at every pace.
"""

from __future__ import annotations

import math
import threading
import time
from typing import Any

CAN_STUFF_WORST = True
"""CAN frame times include the worst-case stuff bits (Tindell's bound)."""


def serial_char_time_s(
    baudrate: float, bytesize: int = 8, parity: str = "N", stopbits: float = 1.0
) -> float:
    """Seconds one character takes on an asynchronous serial line.

    A start bit, ``bytesize`` data bits, one parity bit unless ``parity`` is
    "N", and ``stopbits`` stop bits: 10 bit times for 8N1 (1.04 ms at 9600 baud).
    """
    if not (math.isfinite(baudrate) and baudrate > 0):
        raise ValueError(f"baudrate must be a positive number, got {baudrate!r}")
    bits = 1 + bytesize + (0 if parity == "N" else 1) + stopbits
    return bits / baudrate


def can_frame_time_s(data_bytes: int, bitrate: float, extended_id: bool = False) -> float:
    """Seconds a classic CAN data frame of ``data_bytes`` (0..8) occupies the bus.

    Frame bits (SOF, identifier, control, data, CRC, ACK, EOF and the 3-bit
    interframe space) plus the worst-case stuff bits: for an 11-bit identifier
    ``8n + 47 + floor((34 + 8n - 1) / 4)`` bits, 135 bits for 8 data bytes
    (135 µs at 1 Mbit/s); 29-bit identifiers add 20 frame and 5 stuff bits.
    """
    if not 0 <= data_bytes <= 8:
        raise ValueError(f"a classic CAN frame carries 0..8 bytes, not {data_bytes}")
    if not (math.isfinite(bitrate) and bitrate > 0):
        raise ValueError(f"bitrate must be a positive number, got {bitrate!r}")
    stuffed = 34 + 8 * data_bytes + (20 if extended_id else 0)
    bits = 8 * data_bytes + 47 + (20 if extended_id else 0) + (stuffed - 1) // 4
    return bits / bitrate


class SimClock:
    """The simulated time of one cell, in seconds from the cell's power-up; thread-safe.

    Args:
        time_scale: 0 runs as fast as possible; > 0 makes :meth:`hold` keep
            simulated time from running ahead of ``time_scale`` x wall time
            (1.0 = real time).
    """

    def __init__(self, time_scale: float = 0.0) -> None:
        if not (math.isfinite(time_scale) and time_scale >= 0):
            raise ValueError(f"time_scale must be >= 0 (0 = as fast as possible), got {time_scale}")
        self.time_scale = float(time_scale)
        self._lock = threading.Lock()
        self._now_s = 0.0
        self._anchor: tuple[float, float] | None = None  # (wall s, simulated s)

    @property
    def now_s(self) -> float:
        """The present simulated time, s (one attribute read: atomic, no lock needed)."""
        return self._now_s

    def advance_to(self, t_s: float) -> float:
        """Move the clock forward to ``t_s`` (never back); return the new time."""
        with self._lock:
            if t_s > self._now_s:
                self._now_s = t_s
            return self._now_s

    def advance(self, dt_s: float) -> float:
        """Move the clock forward by ``dt_s`` >= 0 seconds; return the new time."""
        if dt_s < 0:
            raise ValueError(f"time cannot go back ({dt_s} s)")
        with self._lock:
            self._now_s += dt_s
            return self._now_s

    def hold(self) -> None:
        """With a pace set, sleep until wall time has caught up with simulated time.

        The first call anchors simulated time to wall time. A host that falls
        behind (more than 0.5 s of wall time) is re-anchored rather than let
        the emulators answer in a burst to catch up.
        """
        if self.time_scale <= 0:
            return
        with self._lock:
            now_sim = self._now_s
            wall = time.monotonic()
            if self._anchor is None:
                self._anchor = (wall, now_sim)
            wall0, sim0 = self._anchor
            due = wall0 + (now_sim - sim0) / self.time_scale
            if wall - due > 0.5:
                self._anchor = (wall, now_sim)
                due = wall
        delay = due - time.monotonic()
        if delay > 0:
            time.sleep(delay)

    def state_dict(self) -> dict[str, Any]:
        """What a resume restores: the simulated time (s)."""
        with self._lock:
            return {"now_s": self._now_s}

    def load_state_dict(self, state: dict[str, Any]) -> None:
        """Restore :meth:`state_dict`; pacing re-anchors at the next :meth:`hold`."""
        with self._lock:
            self._now_s = float(state["now_s"])
            self._anchor = None


class Wire:
    """One direction of a link: when it is next free, in simulated seconds.

    A transmission starts when both the wire is free and its sender is ready
    (``ready_s``, by default the clock's present time), and lasts ``duration_s``.
    """

    def __init__(self, clock: SimClock) -> None:
        self.clock = clock
        self.free_at_s = 0.0

    def transmit(self, duration_s: float, ready_s: float | None = None) -> tuple[float, float]:
        """Occupy the wire for ``duration_s``; return (start, end) in simulated seconds."""
        ready = self.clock.now_s if ready_s is None else ready_s
        free = self.free_at_s
        start = ready if ready > free else free  # max(free, ready), without the call
        self.free_at_s = end = start + duration_s
        return start, end

    def send(self, duration_s: float, ready_s: float | None = None) -> float:
        """:meth:`transmit`, then the clock moved to the frame's end; returns the end, s.

        ``clock.advance_to(transmit(duration_s, ready_s)[1])`` in one call (the
        in-process routes' frames: a JR3 read puts three on the bus, a status poll four).
        A ``transmit`` wrapped on the object (``step_timeline``'s log) is called.
        """
        end = self.transmit(duration_s, ready_s)[1]
        self.clock.advance_to(end)
        return end

    def state_dict(self) -> dict[str, Any]:
        """The wire's state for a resume."""
        return {"free_at_s": self.free_at_s}

    def load_state_dict(self, state: dict[str, Any]) -> None:
        """Restore :meth:`state_dict`."""
        self.free_at_s = float(state["free_at_s"])
