"""One emulated EGM controller's cycle grid as a step machine (no I/O, no threads).

A controller cycle is two halves, split where the controller waits for the PC:

* :meth:`CycleLoop.begin`: read the EgmSensor answers that reached this cycle,
  honour a restart, build the cycle's EgmRobot and pass it through the send
  faults; it returns the datagrams to send, in order, and whether an answer is
  expected (a lost or held-back datagram expects none);
* :meth:`CycleLoop.end`: take the answers of this cycle (through the reply
  faults: lost, or read one cycle late) and move the cell's clock to the next
  cycle instant: ``t + period``, or the next instant of the grid after the
  clock if another device has moved it further.

Both routes run the same halves: the UDP emulator
(:class:`~forcelearn.emulators.egm.server.EgmControllerEmulator`) between its
socket reads in its own thread, the in-process route
(:class:`~forcelearn.emulators.egm.in_process.InProcessEgmController`) in the
driver's thread inside ``recvfrom`` and ``sendto``. So the two give the same
cycles, datagrams and simulated times for the same traffic.
"""

from __future__ import annotations

import math
import threading
from collections.abc import Callable, Sequence
from typing import Any

from forcelearn.emulators.clock import SimClock
from forcelearn.emulators.egm.controller import EgmControllerModel
from forcelearn.emulators.egm.faults import EgmFaultInjector
from forcelearn.protocols.egm.carried import Datagram


class CycleLoop:
    """The cycle halves of one controller (not thread-safe: one owner drives it).

    Args:
        model: the controller's EGM state.
        faults: the fault injector.
        clock: the cell's simulated clock.
        period_s: the sample period (EGMActPose SampleRate), s.
    """

    def __init__(
        self,
        model: EgmControllerModel,
        faults: EgmFaultInjector,
        clock: SimClock,
        period_s: float,
    ) -> None:
        self.model = model
        self.faults = faults
        self.clock = clock
        self.period_s = period_s
        self.t_s = clock.now_s
        """Simulated time of the present cycle, s."""
        self.cycles = 0
        """Cycles run (EgmRobot datagrams built, sent or not)."""
        self.carried = False
        """Build datagrams not encoded (the in-process route), else wire bytes."""
        self.restart_requested = threading.Event()
        """Set by an operator restart; the next :meth:`begin` starts a new session."""
        self.guidance_stopped = threading.Event()
        """Set when guidance ends (CommTimeout or motion error); cleared by a restart."""
        self._held: Datagram | None = None  # a reordered datagram, sent after the next one
        self._inbox: list[Datagram] = []  # answers read at the next cycle
        self._late: list[Datagram] = []  # read one cycle later still

    def begin(self) -> tuple[list[Datagram], bool]:
        """Start the cycle at :attr:`t_s`; return (datagrams to send, answer expected)."""
        t = self.t_s
        model, faults = self.model, self.faults
        faults.cycle = self.cycles
        for reply in self._inbox:
            model.apply_sensor(reply, t)
        self._inbox, self._late = self._late, []
        quiet = faults.none_armed  # no fault can fire: none is asked (none would draw)
        if (self.restart_requested.is_set()
                or (self.cycles and not quiet and faults.fires("restart"))
                or model.restart_due(t)):
            self.restart_requested.clear()
            model.restart(t)
            self.guidance_stopped.clear()
        if self.carried:  # a force no one reads is not computed while no fault can fire
            datagram: Datagram = model.robot_carried(t, defer_force=quiet)
        else:
            datagram = model.robot_datagram(t)
        if not model.running:
            self.guidance_stopped.set()
        self.cycles += 1
        if quiet and self._held is None:
            return [datagram], True
        out: list[Datagram] = []
        expect, held = True, None
        if faults.fires("lose"):
            expect = False
        elif faults.fires("reorder"):
            expect, held = False, datagram
        else:
            out.append(datagram)
            if faults.fires("duplicate"):
                out.append(datagram)
        if self._held is not None:
            out.append(self._held)
        self._held = held
        return out, expect

    def end(self, replies: Sequence[Datagram]) -> float:
        """Take this cycle's answers and move to the next cycle; return its time, s."""
        faults = self.faults
        if faults.none_armed:
            self._inbox.extend(replies)
        else:
            for reply in replies:
                if faults.fires("lose_reply"):
                    continue
                (self._late if faults.fires("late_reply") else self._inbox).append(reply)
        return self._next_cycle()

    def _next_cycle(self) -> float:
        """Move :attr:`t_s` and the clock to the next cycle instant; return it, s."""
        t = self.t_s  # a resume may have moved the grid meanwhile (load_state_dict)
        next_t = t + self.period_s
        now = self.clock.now_s
        if now > next_t:
            next_t = t + self.period_s * math.ceil((now - t) / self.period_s - 1e-9)
        self.t_s = self.clock.advance_to(next_t)
        return self.t_s

    def rest(self, reply: Datagram, done: Callable[[int, int], bool]) -> tuple[int, int, int]:
        """After ``end([reply])``: run the cycles at rest that follow silently; say how many.

        A cycle at rest (:meth:`EgmControllerModel.can_rest`: the arm rests,
        ``reply`` plans the pose in effect; no fault armed, no restart asked,
        no pace set) changes nothing but the counters, the cycle time and the
        physics' time, so it is run without building its EgmRobot (nor the
        answer: ``reply`` is read again) by :meth:`EgmControllerModel.rest_at`:
        the same state, to the bit, as :meth:`begin` and :meth:`end` give it.
        Cycles run so until one is not at rest or its EgmRobot's stamps
        (header.tm ms, feedBack.time µs) make ``done`` true: that cycle is left
        for :meth:`begin`, in full. Returns (cycles run, and the stamps of the
        last one run, (0, 0) if none).
        """
        model, stamps = self.model, (0, 0)
        if not (self.carried and self.faults.none_armed and self._held is None
                and not self._late and len(self._inbox) == 1 and self._inbox[0] is reply
                and self.clock.time_scale == 0 and model.can_rest(reply)):
            return 0, *stamps
        skipped, restart = 0, self.restart_requested
        while not restart.is_set():
            t = self.t_s
            at = model.stamps(t)
            if done(*at) or not model.rest_at(t):
                break
            self.cycles += 1
            skipped, stamps = skipped + 1, at
            self._next_cycle()  # end([reply]): the inbox holds reply for the next cycle again
        return skipped, *stamps

    def state_dict(self) -> dict[str, Any]:
        """The cycle time, count and the controller's state (JSON-able; the arm is the physics')."""
        return {"t_s": self.t_s, "cycles": self.cycles, "model": self.model.state_dict()}

    def load_state_dict(self, state: dict[str, Any]) -> None:
        """Restore :meth:`state_dict` while a cycle waits for its answer (between the halves).

        Fault injection is not restored (the emulated cell runs none).
        """
        self.t_s = float(state["t_s"])
        self.cycles = int(state["cycles"])
        self.model.load_state_dict(state["model"])
