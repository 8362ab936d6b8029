"""The emulated EGM controller as a running UDP client: socket + cycle loop + faults.

::

    clock = SimClock()
    driver = EgmRobot(EgmConfig(port=0, lockstep=True))
    with EgmControllerEmulator(driver.port, physics=physics, clock=clock):
        driver.wait_for_session()
        ...

The controller is the UDP *client*: it binds 127.0.0.1 (any port, ``port``)
and sends every EgmRobot to the PC's ``remote_host:remote_port``; it reads
the EgmSensor answers arriving from there.

Time (DESIGN.md "Time")
-----------------------
The cycle instants are simulated: cycle k+1 is at t_k + period, or at the next
sample instant after ``clock.now_s`` if another device has moved the clock
further. An EgmSensor received after cycle k is read at cycle k+1 (the
controller reads its input once per cycle).

* ``lockstep=True`` (the emulated cell): after sending cycle k the emulator
  waits for one EgmSensor before it advances the clock, so the number of
  cycles between two host actions is fixed by the traffic. A cycle whose
  EgmRobot was lost or held back (fault) expects no answer. With
  ``patience_s`` set, a PC silent that long (wall time) is declared silent:
  cycles then run at the real 4 ms pace without waiting, and CommTimeout
  follows in simulated time; an answer resumes lockstep.
* ``lockstep=False`` (real pace, the bench): needs ``clock.time_scale > 0``;
  every cycle is sent at its wall time and whatever answers arrived before
  the next cycle are read, the latest winning, as on a real controller.

With ``time_scale > 0`` every cycle is also held until its wall time.
"""

from __future__ import annotations

import logging
import select
import socket
import threading
import time
from dataclasses import dataclass, field
from typing import Any

from forcelearn.emulators.clock import SimClock
from forcelearn.emulators.egm.base import EgmEmulatorBase
from forcelearn.emulators.egm.controller import EgmControllerConfig
from forcelearn.emulators.egm.faults import EgmFaultConfig
from forcelearn.emulators.egm.servo import MotionModel
from forcelearn.emulators.physics.cell import CellPhysics
from forcelearn.protocols.egm.carried import Datagram

log = logging.getLogger(__name__)

POLL_S = 0.05
"""Longest blocking wait of the loop (s): bounds how long stop() takes."""
RESEND_S = 0.2
"""Lockstep: while no answer comes, the cycle's datagram is sent again this often (wall s).

A real controller streams whether or not the PC answers; in lockstep the
emulator stands still instead, so it repeats the waiting cycle's datagram (same
seqno: the driver ignores it as a duplicate). A driver that binds after the
emulator started, or a second client after the first closed (``forcelearn
emulate``), then still receives a cycle to answer. No simulated time passes."""


@dataclass
class CycleTiming:
    """Wall-clock record of a real-pace run (for the bench only, never for results)."""

    send_s: list[float] = field(default_factory=list)
    """perf_counter() at each EgmRobot sent."""
    reply_latency_s: list[float] = field(default_factory=list)
    """From sending a cycle's EgmRobot to the first EgmSensor received after it."""


class EgmControllerEmulator(EgmEmulatorBase):
    """An ABB controller running EGM pose guidance toward a PC at ``remote_port``.

    Args:
        remote_port: the PC's UDP port (the driver's ``port``).
        remote_host: the PC's address (loopback only in tests).
        physics: shared cell physics (default: a fresh one at ``controller.HOME``).
        clock: the cell's simulated clock (default: a new one, as fast as possible).
        config: controller settings (version, sample rate, CommTimeout, servo).
        faults: fault injection (default: none).
        lockstep: wait for the PC's answer before advancing the clock (see module doc).
        patience_s: lockstep only: wall seconds of PC silence before the PC is
            declared silent (None: wait for ever; close() still ends the wait).
        motion: the arm's motion model (default: the config's dead time + lag servo).
        record_timing: keep wall-clock send times and reply latencies (the bench).
    """

    def __init__(
        self,
        remote_port: int,
        *,
        remote_host: str = "127.0.0.1",
        physics: CellPhysics | None = None,
        clock: SimClock | None = None,
        config: EgmControllerConfig | None = None,
        faults: EgmFaultConfig | None = None,
        lockstep: bool = True,
        patience_s: float | None = None,
        motion: MotionModel | None = None,
        record_timing: bool = False,
    ) -> None:
        super().__init__(physics=physics, clock=clock, config=config, faults=faults, motion=motion)
        if not lockstep and self.clock.time_scale <= 0:
            raise ValueError("lockstep=False paces cycles to wall time: needs clock.time_scale > 0")
        self.lockstep = lockstep
        self.patience_s = patience_s
        self.timing = CycleTiming() if record_timing else None
        self._remote = (remote_host, remote_port)
        self._sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self._sock.bind(("127.0.0.1", 0))
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._waiting: bytes | None = None
        """The datagram of the cycle waiting for an answer (lockstep resend)."""
        self.silent = False
        """True while the PC is declared silent (lockstep with patience_s)."""

    @property
    def port(self) -> int:
        """The controller's own UDP port (the source of its EgmRobot datagrams)."""
        return int(self._sock.getsockname()[1])

    @property
    def address(self) -> str:
        """``127.0.0.1:PORT``: where the controller's EgmRobot datagrams come from."""
        return f"127.0.0.1:{self.port}"

    def _start_serving(self) -> None:
        """The cycle loop in a daemon thread."""
        self._thread = threading.Thread(target=self._run, name="egm-controller", daemon=True)
        self._thread.start()
        log.info("EGM controller emulator on 127.0.0.1:%d -> %s:%d", self.port, *self._remote)

    def _release(self) -> None:
        """Stop the loop, join it and close the socket."""
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=5.0)
            if self._thread.is_alive():  # pragma: no cover - would be a bug in _run
                log.error("EGM emulator thread did not stop within 5 s")
        self._thread = None
        self._sock.close()

    def load_state_dict(self, state: dict[str, Any]) -> None:
        """Restore :meth:`state_dict` while the loop waits for the PC's answer (lockstep)."""
        if not self.lockstep:
            raise ValueError("only a lockstep emulator can be restored")
        super().load_state_dict(state)

    # -- the cycle loop ---------------------------------------------------------------------

    def _run(self) -> None:
        loop = self.loop
        period = self.config.sample_period_s
        loop.t_s = self.clock.now_s  # the grid starts when serving starts
        wall0, t0 = time.monotonic(), loop.t_s
        try:
            while not self._stop.is_set():
                out, expect_reply = loop.begin()
                self._waiting = bytes(out[0]) if expect_reply else None
                for datagram in out:
                    self._send(datagram)
                self.clock.hold()
                if self.lockstep:
                    replies = self._await_reply(expect_reply)
                else:
                    replies = self._drain_until(wall0 + (loop.t_s + period - t0)
                                                / self.clock.time_scale)
                loop.end(replies)
        except OSError as exc:
            if not self._stop.is_set():
                log.error("EGM emulator socket failed: %s", exc)

    def _send(self, datagram: Datagram) -> None:
        if self.timing is not None:
            self.timing.send_s.append(time.perf_counter())
        self._sock.sendto(bytes(datagram), self._remote)

    def _receive(self, timeout_s: float) -> bytes | None:
        ready, _, _ = select.select([self._sock], [], [], max(timeout_s, 0.0))
        if not ready:
            return None
        data, address = self._sock.recvfrom(65535)
        if address[1] != self._remote[1]:
            log.info("datagram from %s ignored: not the configured PC", address)
            return None
        self.replies += 1
        if self.timing is not None and self.timing.send_s:
            latency = time.perf_counter() - self.timing.send_s[-1]
            if len(self.timing.reply_latency_s) < len(self.timing.send_s):
                self.timing.reply_latency_s.append(latency)
        return data

    def _await_reply(self, expect_reply: bool) -> list[bytes]:
        """Lockstep: wait for one EgmSensor (if one is due), honouring patience and stop()."""
        if not expect_reply:
            return []
        if self.silent:  # real pace, no waiting, until the PC speaks again
            reply = self._receive(self.config.sample_period_s)
            if reply is not None:
                self.silent = False
            return [reply] if reply is not None else []
        deadline = None if self.patience_s is None else time.monotonic() + self.patience_s
        sent = time.monotonic()
        while not self._stop.is_set():
            wait = POLL_S if deadline is None else min(POLL_S, deadline - time.monotonic())
            reply = self._receive(wait)
            if reply is not None:
                return [reply]
            if self._waiting is not None and time.monotonic() - sent >= RESEND_S:
                self._sock.sendto(self._waiting, self._remote)  # see RESEND_S
                sent = time.monotonic()
            if deadline is not None and time.monotonic() >= deadline:
                log.info("the PC has been silent for %.3f s: cycles go on without it",
                         self.patience_s)
                self.silent = True
                return []
        return []

    def _drain_until(self, due_wall_s: float) -> list[bytes]:
        """Real pace: collect every EgmSensor that arrives before the next cycle's wall time."""
        replies = []
        while not self._stop.is_set():
            remaining = due_wall_s - time.monotonic()
            reply = self._receive(min(max(remaining, 0.0), POLL_S))
            if reply is not None:
                replies.append(reply)  # drain what has arrived even when behind time
            elif remaining <= 0:
                break
        return replies[-1:]  # the latest one wins
