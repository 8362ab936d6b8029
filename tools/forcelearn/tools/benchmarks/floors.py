"""The machine's floors: what the host's kernel, python-can and numpy cost, measured now.

Every speed figure of ``forcelearn bench all`` is printed as a ratio to one of
these, measured in the same run, so a figure means the same on a fast idle
machine and on a slow shared one (docs/performance.md):

=============  ================================================================
floor          what is timed
=============  ================================================================
pty echo       a 24-byte frame written by pyserial to a pty, echoed back by a
               thread on the emulators' pty endpoint, read whole: the round
               trip, p50 (s). The target for a computer-link move counts two
               such exchanges; the move's own exchange is one round trip and
               a write (:mod:`.protocol_floors` times it).
CAN round      a frame sent on a python-can ``virtual`` bus, received by a
trip           thread on a second bus of the channel and sent back: round
               trips per second. The floor of a JR3 sync read (SYNC out,
               force and moment frames back).
foam step      one numpy step of the foam law over 64 cells: penetration,
               elastic depth, the relaxing part's exact update and the normal
               force (``physics.sponge``'s law on arrays), s. The floor of a
               vectorised environment's step.
=============  ================================================================
"""

from __future__ import annotations

import statistics
import threading
import time
import uuid
from dataclasses import dataclass

import can
import numpy as np
import serial

from forcelearn.emulators.physics.sponge import SpongeParams
from forcelearn.emulators.pty_endpoint import PtyEndpoint

FRAME_BYTES = 24
"""Bytes of the echoed frame (about a computer-link move frame with its DLE stuffing)."""


@dataclass(frozen=True)
class Floors:
    """The three floors of one run."""

    pty_echo_s: float
    """pty echo round trip, p50, s."""
    can_round_trips_per_s: float
    """python-can virtual bus round trips per second (median of the repeats)."""
    foam_step_s: float
    """One numpy foam-law step over 64 cells, s (median)."""


def pty_echo_s(rounds: int = 2000) -> float:
    """Return the p50 round trip (s) of a ``FRAME_BYTES`` frame echoed through a pty.

    The two ends are the link's: the emulators' :class:`PtyEndpoint` echoing in
    a thread of its own, and a pyserial port on the other side, as the driver
    opens it.
    """
    endpoint = PtyEndpoint("floor")
    stop = threading.Event()

    def echo() -> None:
        while not stop.is_set():
            data = endpoint.read(0.05)
            if data:
                endpoint.write(data)

    thread = threading.Thread(target=echo, name="pty-echo", daemon=True)
    thread.start()
    frame = bytes(range(FRAME_BYTES))
    times = np.empty(rounds)
    try:
        with serial.Serial(endpoint.address, timeout=1.0) as port:
            for i in range(rounds + 100):
                start = time.perf_counter()
                port.write(frame)
                if len(port.read(FRAME_BYTES)) != FRAME_BYTES:
                    raise RuntimeError("the pty echo thread did not answer within 1 s")
                if i >= 100:
                    times[i - 100] = time.perf_counter() - start
    finally:
        stop.set()
        thread.join(1.0)
        endpoint.close()
    return float(np.percentile(times, 50))


def can_round_trips_per_s(rounds: int = 3000, repeats: int = 3) -> float:
    """Return round trips per second through a python-can ``virtual`` channel (median)."""
    rates = []
    for _ in range(repeats):
        channel = f"floor-{uuid.uuid4().hex[:8]}"
        with can.Bus(interface="virtual", channel=channel) as host, \
                can.Bus(interface="virtual", channel=channel) as far:
            stop = threading.Event()

            def echo(bus: can.BusABC = far, done: threading.Event = stop) -> None:
                while not done.is_set():
                    msg = bus.recv(0.05)
                    if msg is not None:
                        bus.send(can.Message(arbitration_id=msg.arbitration_id + 1,
                                             data=msg.data, is_extended_id=False))

            thread = threading.Thread(target=echo, name="can-echo", daemon=True)
            thread.start()
            msg = can.Message(arbitration_id=0x100, data=bytes(8), is_extended_id=False)
            try:
                for _ in range(100):
                    host.send(msg)
                    host.recv(1.0)
                start = time.perf_counter()
                for _ in range(rounds):
                    host.send(msg)
                    if host.recv(1.0) is None:
                        raise RuntimeError("the CAN echo thread did not answer within 1 s")
                rates.append(rounds / (time.perf_counter() - start))
            finally:
                stop.set()
                thread.join(1.0)
    return float(statistics.median(rates))


def foam_step_s(cells: int = 64, rounds: int = 5000) -> float:
    """Return the time (s) of one numpy step of the foam law over ``cells`` cells (median)."""
    p = SpongeParams()
    rng = np.random.default_rng(0)
    y = rng.uniform(-12.0, 0.0, cells)
    z = rng.uniform(p.z_bottom_mm, p.z_top_mm, cells)
    q = np.zeros(cells)
    u_old = np.zeros(cells)
    dt_s = 0.004
    decay = np.exp(-dt_s / p.relaxation_time_s)
    wave_k = 2.0 * np.pi / p.waviness_wavelength_mm
    stiff_k = 2.0 * np.pi / p.stiffness_wavelength_mm
    chunk = 100
    times = []
    force = np.zeros(cells)
    for _ in range(rounds // chunk):
        start = time.perf_counter()
        for _ in range(chunk):
            travelled = p.z_top_mm - z
            surface = (p.surface_y_mm + p.surface_slope * travelled
                       + p.waviness_mm * np.sin(wave_k * travelled))
            u = np.clip(surface - y, 0.0, p.thickness_mm)
            q = q * decay + (u - u_old) * (1.0 - decay) * p.relaxation_time_s / dt_s
            stiffness = p.stiffness_n_per_mm * (1.0 + p.stiffness_variation * np.cos(
                stiff_k * travelled))
            force = stiffness * np.maximum(0.0, u + p.relaxation_ratio * q)
            u_old = u
        times.append((time.perf_counter() - start) / chunk)
    if not np.all(np.isfinite(force)):
        raise RuntimeError("the foam step gave a non-finite force")
    return float(statistics.median(times))


def measure() -> Floors:
    """Measure the three floors now."""
    return Floors(pty_echo_s(), can_round_trips_per_s(), foam_step_s())
