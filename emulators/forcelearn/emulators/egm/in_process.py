"""The emulated EGM controller in the driver's own thread: a socket-like object, no UDP.

::

    controller = InProcessEgmController(physics=physics, clock=physics.clock)
    driver = EgmRobot(EgmConfig(lockstep=True), sock=controller.socket())
    driver.wait_for_session()

:meth:`InProcessEgmController.socket` gives what the driver would otherwise
bind: an object with the ``sendto``/``recvfrom``/``settimeout``/``getsockname``/
``close`` of a UDP socket (the driver's ``DatagramSocket``). The controller has
no thread: ``recvfrom`` runs the controller's next cycle
(:meth:`CycleLoop.begin <forcelearn.emulators.egm.cycles.CycleLoop.begin>`) and
returns its EgmRobot; ``sendto`` hands the EgmSensor over and ends the cycle
(:meth:`~forcelearn.emulators.egm.cycles.CycleLoop.end`). The bytes are the
same as over loopback UDP, and so are the cycles and simulated times, since
both routes run the same cycle halves in the same order; what goes is the
hand-over between two threads per 4 ms cycle, most of an emulated EGM run's
wall time.

Lockstep only, as the UDP emulator in the emulated cell. Where the UDP route
waits for an answer that the PC never sends, this one cannot wait (nothing
else runs): a ``recvfrom`` while the cycle's answer is due lets that cycle go
on unanswered, as a real controller does (it reuses the last EgmSensor), and
a PC that keeps reading without answering reaches CommTimeout in simulated
time. One client at a time.
"""

from __future__ import annotations

import logging
from collections import deque
from typing import Any

from forcelearn.emulators.egm.base import EgmEmulatorBase
from forcelearn.emulators.egm.cycles import Answer
from forcelearn.protocols.egm.carried import Carried, Datagram

log = logging.getLogger(__name__)

SOURCE = ("in-process", 0)
"""The address the in-process controller's datagrams come from."""


class InProcessEgmController(EgmEmulatorBase):
    """An emulated ABB controller driven by its client's calls (see the module doc).

    Takes the arguments of :class:`~forcelearn.emulators.egm.base.EgmEmulatorBase`.
    """

    rests = True
    """Run the cycles whose answers the client computes in one jump when it asks
    (``rest_carried``); False: every cycle in full (what the tests compare the jump with)."""

    def __init__(self, **kwargs: Any) -> None:
        super().__init__(**kwargs)
        self.loop.carried = True  # nothing here needs the bytes: they are made when asked
        self._outbox: deque[Datagram] = deque()
        self._early: list[Datagram] = []  # answers sent while none was due: the next due one
        self._awaiting = False  # the present cycle's answer is due
        self._client: InProcessDatagramSocket | None = None
        self.unanswered = 0
        """Cycles whose due answer never came (the client read on without answering)."""
        self.rested = 0
        """Cycles run silently (their answers computed by the client, unseen)."""
        self._mark_started()

    @property
    def address(self) -> str:
        """``in-process``: reached through :meth:`socket`, not an address."""
        return "in-process"

    def socket(self) -> InProcessDatagramSocket:
        """The one client's socket-like end (pass it to ``EgmRobot(sock=...)``)."""
        if self.closed:
            raise RuntimeError("this InProcessEgmController was closed; create a new one")
        if self._client is not None and not self._client.closed:
            raise RuntimeError("the in-process EGM controller has a client already; close it first")
        self._client = InProcessDatagramSocket(self)
        return self._client

    def _release(self) -> None:
        self._outbox.clear()

    # -- the two halves, driven by the client ---------------------------------------------

    def _next_datagram(self) -> Datagram:
        """Run cycles until one has a datagram to send; return it."""
        loop = self.loop
        while not self._outbox:
            if self._awaiting:  # read on without answering: the cycle goes on unanswered
                self._awaiting = False
                self.unanswered += 1
                loop.end([])
                continue
            out, expect = loop.begin()
            self._outbox.extend(out)
            self.clock.hold()
            if not expect:
                loop.end([])
            elif self._early:
                loop.end([self._early.pop(0)])
            else:
                self._awaiting = True
        return self._outbox.popleft()

    def _answer(self, datagram: Datagram) -> None:
        """Take one EgmSensor: it ends the cycle that waits for it, or the next one that will."""
        self.replies += 1
        if self._awaiting:
            self._awaiting = False
            self.loop.end([datagram])
        else:
            self._early.append(datagram)


    def _rest(self, datagram: Datagram, answer: Answer) -> tuple[int, int, int]:
        """Answer the due cycle with ``datagram``, then jump what ``answer`` answers (loop.rest)."""
        self._answer(datagram)
        if not self.rests or self._outbox or self._early or self._awaiting:
            return 0, 0, 0
        skipped, tm_ms, time_us, robot = self.loop.rest(datagram, answer)
        self.replies += skipped
        self.rested += skipped
        if robot is not None:  # the cycle the jump ended on waits for its answer (as begin's)
            self._outbox.append(robot)
            self._awaiting = True
        return skipped, tm_ms, time_us


class InProcessDatagramSocket:
    """The client's end: what the EGM driver calls instead of a bound UDP socket."""

    def __init__(self, controller: InProcessEgmController) -> None:
        self._controller = controller
        self.closed = False

    def _require_open(self) -> InProcessEgmController:
        if self.closed:
            raise OSError("this in-process EGM socket is closed")
        if self._controller.closed:
            raise OSError("the in-process EGM controller was closed")
        return self._controller

    def recvfrom(self, bufsize: int, /) -> tuple[bytes, tuple[str, int]]:
        """Run the controller to its next datagram and return its bytes (never blocks)."""
        datagram = bytes(self._require_open()._next_datagram())
        return (datagram if len(datagram) <= bufsize else datagram[:bufsize]), SOURCE

    def sendto(self, data: bytes, address: Any, /) -> int:
        """Hand an EgmSensor to the controller (``address`` is not used)."""
        self._require_open()._answer(bytes(data))
        return len(data)

    def recv_carried(self) -> tuple[Datagram, tuple[str, int]]:
        """:meth:`recvfrom`, the datagram not encoded (the driver reads its message as it is)."""
        return self._require_open()._next_datagram(), SOURCE

    def send_carried(self, data: Datagram, address: Any, /) -> None:
        """:meth:`sendto` of a datagram not encoded (the controller reads its message)."""
        self._require_open()._answer(data if type(data) is Carried else bytes(data))

    def rest_carried(
        self, data: Datagram, address: Any, answer: Answer, /
    ) -> tuple[int, int, int]:
        """:meth:`send_carried`, then the cycles whose answers ``answer`` gives, in one jump.

        While the answers plan poses the controller may read unseen (no
        speedRef, guidance running, :meth:`CycleLoop.rest
        <forcelearn.emulators.egm.cycles.CycleLoop.rest>`), each cycle whose
        EgmRobot (header.tm ms, feedBack.time µs, feedBack.cartesian,
        planned.cartesian) ``answer`` answers with a planned pose is run
        without building either message (the controller's state, the cell's
        physics and the clock as cycle by cycle, to the bit); the first one
        it answers None is what :meth:`recv_carried` gives next. Returns
        (cycles jumped, the last one's header.tm and feedBack.time; 0
        cycles: none, and the stamps are 0).
        """
        return self._require_open()._rest(data if type(data) is Carried else bytes(data), answer)

    def settimeout(self, value: float | None, /) -> None:
        """Accepted and not needed: nothing here ever waits."""

    def getsockname(self) -> tuple[str, int]:
        """``("in-process", 0)``."""
        return SOURCE

    def close(self) -> None:
        """Detach from the controller (idempotent); the controller keeps its state."""
        self.closed = True
