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

from forcelearn.devices import Pose
from forcelearn.emulators.clock import SimClock
from forcelearn.emulators.egm.controller import EgmControllerModel
from forcelearn.emulators.egm.faults import EgmFaultInjector
from forcelearn.protocols.egm.carried import Datagram

Answer = Callable[[int, int, Pose, Pose], Pose | None]
"""The planned pose of the PC's answer to an EgmRobot, from its header.tm (ms), feedBack.time
(µs), feedBack.cartesian and planned.cartesian; None: the PC reads that EgmRobot itself
(:meth:`CycleLoop.rest` stops its jump there).

It may also have ``at_rest(feedback, planned, stamps) -> int``: for cycles of these
(header.tm, feedBack.time) in order, all with this feedback and planned pose, how many
leading ones it answers with ``planned`` itself, found as it would answer them one by one
(its own state changes included); the cycle at that index (if any) it answers None. -1:
not known (each cycle is asked). :meth:`CycleLoop.rest` asks it for runs of cycles at rest."""

REST_RUN = 128
"""Cycles at rest whose answers one ``at_rest`` call gives (:meth:`CycleLoop._rest_batch`)."""


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

    def rest(self, reply: Datagram, answer: Answer) -> tuple[int, int, int, Datagram | None]:
        """After ``end([reply])``: the cycles that follow whose answer the PC computes unseen.

        While no fault is armed, no restart asked, no pace set and ``reply``
        plans a pose with no speedRef (:meth:`EgmControllerModel.readable`),
        a cycle reads the planned pose (:meth:`EgmControllerModel.read_planned`:
        the checks, the arm's new segment, or the pose in effect again), moves
        the cell and builds the EgmRobot the PC reads to decide its answer:
        ``answer(tm_ms, time_us, feedback, planned)`` of that EgmRobot's
        header.tm, feedBack.time, feedBack.cartesian and planned.cartesian
        gives the planned pose of the PC's next EgmSensor, or None when the
        PC must read this EgmRobot itself (its wait ends, or it would withhold
        its answer). Such cycles run here, one by one on the model (the same
        state to the bit as :meth:`begin` and :meth:`end`), without building
        an EgmRobot nor its answer; the first one ``answer`` refuses (or one
        that stops guidance, a restart, or the seqno wrapping next) is run up
        to its EgmRobot, returned to be sent (the cycle then waits for its
        answer, as after :meth:`begin`). Returns (cycles skipped, the last
        one's stamps or (0, 0), that EgmRobot or None: no cycle was run for
        it, :meth:`begin` runs the next).
        """
        model, stamps = self.model, (0, 0)
        if not (self.carried and self.faults.none_armed and self._held is None
                and not self._late and len(self._inbox) == 1 and self._inbox[0] is reply
                and self.clock.time_scale == 0):
            return 0, *stamps, None
        planned = model.readable(reply)
        restart = self.restart_requested
        if planned is None or model.wraps() or restart.is_set():
            return 0, *stamps, None
        skipped = 0
        while True:
            t = self.t_s
            if restart.is_set():  # an operator restart meanwhile: read, then as begin
                model.read_planned(planned, t)
                self.cycles += 1
                self._inbox = []
                restart.clear()
                model.restart(t)
                self.guidance_stopped.clear()
                return skipped, *stamps, model.robot_carried(t, defer_force=True)
            pose = model.rest_pose(planned) if self.clock.now_s == t else None
            if pose is not None:  # cycles at rest, in a batch (_rest_batch)
                skipped, stamps, planned, robot = self._rest_batch(
                    planned, pose, answer, skipped, stamps)
                if robot is not None:
                    return skipped, *stamps, robot
                continue
            if self.clock.now_s == t and model.run_start():  # the moving arm's cycles, a run
                ran, skipped, stamps, planned, robot = self._follow_run(
                    planned, answer, skipped, stamps)
                if robot is not None:
                    return skipped, *stamps, robot
                if ran:
                    continue
            feedback = model.follow_cycle(planned, t)  # read_planned, then move_to
            self.cycles += 1
            self._inbox = []  # read
            at = model.stamps(t)
            step = None
            if model.running and not model.wraps_next():
                step = answer(*at, feedback, model.planned)
            if step is None:
                if not model.running:
                    self.guidance_stopped.set()
                return skipped, *stamps, model.robot_carried(t, defer_force=True, moved=True)
            model.skip()
            skipped, stamps, planned = skipped + 1, at, step
            self._next_cycle()  # end([the answer]): read at the next cycle

    def _follow_run(
        self, planned: Pose, answer: Answer, skipped: int, stamps: tuple[int, int]
    ) -> tuple[int, int, tuple[int, int], Pose, Datagram | None]:
        """:meth:`rest`'s cycles one by one while the arm moves: ramps and the arm's lag.

        The same cycles, answers and state as :meth:`rest`'s loop
        (:meth:`EgmControllerModel.run_cycle` for ``follow_cycle``), the cell's side of
        the arm's ticks taken at the end (:meth:`EgmControllerModel.run_end`). Ends
        once the arm rests while the answer repeats the pose, before a restart, the
        cycle whose seqno wraps next or a cycle ``run_cycle`` leaves (a refusal), or
        at the cycle the PC reads (its EgmRobot returned). Returns (cycles run, cycles
        skipped, their last stamps, the planned pose of the next cycle, the EgmRobot
        to send or None).
        """
        model, restart, period = self.model, self.restart_requested, self.period_s
        t = self.t_s
        left = model.cycles_to_wrap()  # the cycle after which the seqno wraps is read by rest()
        ran = answered = 0  # (the answered cycles' EgmRobots counted as built at the end)
        try:
            while ran < left and not restart.is_set():
                cycle = model.run_cycle(t, planned)
                if cycle is None:  # this cycle runs one by one (nothing done)
                    break
                feedback, resting = cycle
                self.cycles += 1
                self._inbox = []  # read
                ran += 1
                at = model.stamps(t)
                step = answer(*at, feedback, planned)
                if step is None:  # the PC reads this cycle's EgmRobot
                    model.skip(answered)
                    answered = 0
                    model.run_end()
                    self.t_s = self.clock.advance_to(t)
                    robot = model.robot_carried(t, defer_force=True, moved=True)
                    return ran, skipped, stamps, planned, robot
                answered += 1
                skipped, stamps = skipped + 1, at
                t = t + period  # end([the answer]): read at the next cycle
                if step is planned and resting:
                    break
                planned = step
        finally:
            if answered:
                model.skip(answered)
            model.run_end()
        self.t_s = self.clock.advance_to(t)
        return ran, skipped, stamps, planned, None

    def _rest_batch(
        self, planned: Pose, pose: Pose, answer: Answer, skipped: int, stamps: tuple[int, int]
    ) -> tuple[int, tuple[int, int], Pose, Datagram | None]:
        """:meth:`rest`'s cycles while they read ``planned`` and the arm rests at ``pose``.

        Such a cycle (:meth:`EgmControllerModel.rest_pose`) changes nothing the
        PC's answer reads but its stamps (the feedback and planned pose stay), and
        the answer changes nothing the cycle does: so the answers are taken first,
        cycle by cycle at the cycles' times (``t + period`` each, as
        :meth:`_next_cycle` when nothing else moved the clock), then the model and
        the arm run those cycles in one call (:meth:`EgmControllerModel.rest_through`:
        the sponge's ticks, the read time and count, the speed) and the clock moves
        to the last. The batch ends before a cycle at which a restart is asked,
        after the first whose answer plans another pose (returned, read next),
        or at the first the PC reads itself (its EgmRobot returned, as in
        :meth:`rest`). Returns (cycles skipped, their last stamps, the planned
        pose of the next cycle, the EgmRobot to send or None).
        """
        model, restart, period = self.model, self.restart_requested, self.period_s
        t = self.t_s
        times: list[float] = []
        left = model.cycles_to_wrap()  # the cycle after which the seqno wraps is read by the PC
        step: Pose | None = planned
        last_at = stamps
        at = stamps
        at_rest = getattr(answer, "at_rest", None)
        while True:
            if restart.is_set():  # the next cycle (at t) runs as rest() runs it
                break
            if at_rest is not None and len(times) < left:  # a run of answers in one call
                run_t: list[float] = []
                for _ in range(min(REST_RUN, left - len(times))):
                    run_t.append(t)
                    t = t + period
                run_at = model.stamps_at(run_t)
                answered = at_rest(pose, planned, run_at)
                if answered >= 0:
                    times += run_t[:answered]
                    if answered:
                        last_at = at = run_at[answered - 1]
                    if answered == len(run_t):
                        continue  # all answered with planned: t is the next cycle's
                    at, step, t = run_at[answered], None, run_t[answered]  # the PC reads it
                    times.append(t)
                    break
                at_rest, t = None, run_t[0]  # not known: each cycle is asked
            at = model.stamps(t)
            step = answer(*at, pose, planned) if len(times) < left else None
            times.append(t)
            if step is not planned:
                break
            last_at = at
            t = t + period
        if not times:
            self.t_s = self.clock.advance_to(t)
            return skipped, stamps, planned, None
        model.rest_through(times)
        self.cycles += len(times)
        self._inbox = []  # read
        if step is None:  # the PC reads this cycle's EgmRobot (the wait ends, or the seqno wraps)
            done = len(times) - 1
            model.skip(done)
            self.t_s = self.clock.advance_to(times[-1])
            robot = model.robot_carried(times[-1], defer_force=True, moved=True)
            return skipped + done, last_at if done else stamps, planned, robot
        model.skip(len(times))
        self.t_s = self.clock.advance_to(times[-1])
        if step is planned:  # stopped before a restart: the next cycle is due at t
            self.t_s = self.clock.advance_to(t)
            return skipped + len(times), last_at, planned, None
        self._next_cycle()  # end([the answer]): read at the next cycle
        return skipped + len(times), at, step, None

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
