"""Faults at random instants of a run on the emulated cell, and the truth to judge it by.

:class:`Injector` counts the cell's device calls (every waited move and every
burst, the recovery's own included) and, at instants drawn beforehand, makes a
device fail through its emulator's fault hooks. :class:`Truth` watches the
emulated physics, never the readings: the contact force at every motion tick,
where each zero is taken, and the error of every accepted reading.

=================  ===========================================================
fault              what the emulator does
=================  ===========================================================
``reboot``         JR3: power-cycle (bootup frame, offsets lost); Net F/T: reboot
                   (``ft_sequence`` restarts, software bias lost)
``silence``        the sensor sends nothing for the next 1 to 3 bursts
``corrupt``        JR3: the next 2 to 12 frames with a wrong length; Net F/T:
                   the next 2 to 12 datagrams the box sends arrive damaged (cut
                   short, run long, the error bit in a record's status, or 36
                   bytes of garbage: :meth:`Injector._netft_corrupt`)
``bias_jump``      the sensor's bias on the normal axis jumps by ±1 to 8 N
``restart``        computer link: the arm halts where it is and the link drops;
                   EGM: the controller restarts guidance (a new session)
``stall``          the next move stops at 20 to 80 % of its way (never in position)
``link_drop``      computer link: the connection drops after the next request;
                   EGM: the next 1 to 250 controller datagrams are lost (up to 1 s,
                   absorbed) or, one time in three, 251 to 2,000 (``long_link_drop``
                   in the reports; 1 to 8 s: past
                   the controller's 1 s CommTimeout, which stops guidance until its
                   RAPID program opens a new session, as rapid/ForcelearnEGM.modx
                   does 1 s later)
``kill``           the process dies here (no clean-up); the campaign resumes it
=================  ===========================================================
"""

from __future__ import annotations

import dataclasses
import math
import random
import time
from collections import Counter
from collections.abc import Callable
from typing import Any

import numpy as np

from forcelearn.cell import Cell
from forcelearn.emulators.computer_link.faults import ComputerLinkFaultConfig, FaultInjector
from forcelearn.emulators.egm.faults import EgmFaultConfig, EgmFaultInjector
from forcelearn.emulators.faults import Fault
from forcelearn.protocols.jr3_can.codec import Frame
from forcelearn.protocols.netft import RECORD

SENSOR_FAULTS = ("reboot", "silence", "corrupt", "bias_jump")
RDT_RECORD_SIZE = RECORD.size
"""Bytes of one Net F/T RDT record (36)."""
RDT_ERROR_STATUS = 0x80000000
"""A status word with the box's error bit (bit 31: "system error") set."""
EGM_LOST_MAX = 250
"""Most controller datagrams a short EGM ``link_drop`` loses (4 ms cycles: 1 s)."""
EGM_LONG_LOST_MAX = 2000
"""Most controller datagrams a long EGM ``link_drop`` loses (8 s: past the CommTimeout)."""
EGM_LONG_SHARE = 1 / 3
"""The share of EGM ``link_drop`` faults that are long."""
ROBOT_FAULTS = ("restart", "stall", "link_drop")
RUN_FAULTS = ("kill",)



def shift_sensor_bias(session: Any, reading_change_n: float) -> None:
    """Move the emulated sensor's bias so the normal force reads ``reading_change_n`` more, N.

    ``session``: a :class:`~forcelearn.site.CellSession` with an emulated sensor (JR3 or
    Net F/T: their models keep the bias in ``state_dict()["bias"]``).
    """
    model = session.sensor_emulator.model
    normal = session.cell.force_filter.config
    state = model.state_dict()
    bias = np.array(state["bias"], dtype=float)
    bias[normal.axis] += normal.sign * reading_change_n
    state["bias"] = bias
    model.load_state_dict(state)

class Killed(BaseException):
    """The process "died" (a kill at this instant): nothing below may catch it."""


@dataclasses.dataclass
class Fired:
    """One fault fired: which, where and when (cell time, s)."""

    device: str
    kind: str
    tick: int
    cell_time_s: float
    events_before: int = 0
    """Lines of the run's ``faults.jsonl`` when it fired."""
    session: int = 0
    """The run's session (a resume opens another) it fired in."""
    in_contact: bool = False
    """The tool touched the part when it fired."""


@dataclasses.dataclass(frozen=True)
class Mark:
    """When something happened: device call (tick), session, cell time s, wall time s."""

    tick: int
    session: int
    cell_time_s: float
    wall_s: float


class Truth:
    """What the emulated physics says, whatever the sensor reads.

    Args:
        session: an open emulated :class:`~forcelearn.site.session.CellSession`.
        tolerance_n: largest error of a reading still called good, N.
        sigma_n: the sensor's noise sigma, N (used readings beyond 3 sigma are counted).
    """

    def __init__(self, session: Any, tolerance_n: float, sigma_n: float = float("inf")) -> None:
        self.session = session
        self.physics = session.physics
        self.tolerance_n = tolerance_n
        self.sigma_n = sigma_n
        self.beyond_3sigma = 0
        """Used readings more than 3 sigma of the sensor's noise from the true force."""
        self.max_contact_n = 0.0
        self.zeros = 0
        self.zeros_in_contact = 0
        self.readings = 0
        """Readings the run used: booked with a whole trial (or the probe) it kept."""
        self.worst_error_n = 0.0
        self.bad_readings: Counter[str] = Counter()
        """Used readings off by more than the tolerance, by the fault to blame: a bias jump not
        yet zeroed away, else the last fault fired before them."""
        self.voided = 0
        """Readings of trials (or probes) the run rolled back: never used, kept in voided.jsonl."""
        self.voided_bad: Counter[str] = Counter()
        """Voided readings off by more than the tolerance, by the fault to blame."""
        self.worst_used_n = 0.0
        """The largest error of a used reading, N."""
        self._pending: list[tuple[float, str | None]] = []
        """Readings since the last booking: (error N, the fault to blame if off, else None)."""
        self.jumped = False
        """A bias jump happened and no zero followed yet."""
        self._burst: list[float] = []
        """The true normal force at each sensor sample since :meth:`begin_burst`, N."""
        self._hook_physics()
        self._hook_zero()
        self._hook_samples()

    def contact_n(self) -> float:
        """Magnitude of the contact force the sponge exerts now, N."""
        force = self.physics.environment.contact_force_world_n(self.physics._position_mm)
        return float(np.linalg.norm(force))

    def normal_n(self) -> float:
        """The normal (+Y) contact force now, N."""
        force = self.physics.environment.contact_force_world_n(self.physics._position_mm)
        return float(force[1])

    def judge_reading(self, reading_n: float, last_fault: str) -> None:
        """Judge a reading the cell accepted (a bad one is charged to ``last_fault``).

        It counts as used once the run books it (:meth:`commit`), as voided when
        the run rolls it back (:meth:`void`) or never books it (:meth:`finish`).
        """
        truth = sum(self._burst) / len(self._burst) if self._burst else self.normal_n()
        error = abs(reading_n - truth)  # against what the burst's samples met (a foam relaxes)
        self.worst_error_n = max(self.worst_error_n, error)
        bad = ("bias_jump" if self.jumped else last_fault) if error > self.tolerance_n else None
        self._pending.append((error, bad))

    def commit(self) -> None:
        """The run booked a trial (records written): the readings since are used."""
        self.readings += len(self._pending)
        self.beyond_3sigma += sum(e > 3.0 * self.sigma_n for e, _ in self._pending)
        self.bad_readings.update(b for _, b in self._pending if b is not None)
        self.worst_used_n = max([self.worst_used_n, *(e for e, _ in self._pending)])
        self._pending = []

    def void(self) -> None:
        """The run rolled a trial back: the readings since the last booking are void."""
        self.voided += len(self._pending)
        self.voided_bad.update(b for _, b in self._pending if b is not None)
        self._pending = []

    def finish(self) -> None:
        """The session ended: what it read and never booked is void (a resume runs it again)."""
        self.void()

    def zeroed_in_software(self) -> None:
        """The cell took a zero of its own (the zero check's burst): judged as a sensor's zero."""
        self.zeros += 1
        self.jumped = False
        if self.contact_n() > 0.0:
            self.zeros_in_contact += 1

    def begin_burst(self) -> None:
        """A burst is read next: its samples' true forces are what its reading is judged by."""
        self._burst = []

    def _hook_samples(self) -> None:
        physics, true_wrench = self.physics, self.physics.true_wrench

        def sampled() -> np.ndarray:
            self._burst.append(self.normal_n())
            wrench: np.ndarray = true_wrench()
            return wrench

        physics.true_wrench = sampled

    def _hook_physics(self) -> None:
        physics, move = self.physics, self.physics._move_tool

        def moved(key: Any) -> None:
            move(key)
            self.max_contact_n = max(self.max_contact_n, self.contact_n())

        physics._move_tool = moved

    def _hook_zero(self) -> None:
        model = self.session.sensor_emulator.model
        name = "zero" if hasattr(model, "zero") else "set_software_bias"
        zero = getattr(model, name)

        def zeroed(true_wrench: np.ndarray) -> None:
            self.zeros += 1
            self.jumped = False
            if self.contact_n() > 0.0:
                self.zeros_in_contact += 1
            zero(true_wrench)

        setattr(model, name, zeroed)


class Injector:
    """Fires the planned faults at their ticks (device calls) of one run, across sessions.

    Args:
        plan: tick -> list of (device role "robot"/"sensor"/"run", fault kind).
        rng: draws the faults' sizes and lengths.
    """

    def __init__(self, plan: dict[int, list[tuple[str, str]]], rng: random.Random) -> None:
        self.plan = plan
        self.rng = rng
        self.tick = 0
        self.fired: list[Fired] = []
        self.stops: list[Mark] = []
        """Every robot stop."""
        self.reads: list[Mark] = []
        """Every sensor read (a burst, a guard sample, a restart), as it starts."""
        self.sessions = 0
        self.session: Any = None
        self.truth: Truth | None = None
        self._undo: list[tuple[int, Any]] = []
        self._after_move: list[Any] = []
        self._last = "none"
        self.events: Callable[[], int] = lambda: 0
        """Counts the run's fault events so far (set by the campaign)."""

    def attach(self, session: Any, truth: Truth) -> None:
        """Watch a newly opened session's cell (a resumed run opens a new one)."""
        self.session, self.truth = session, truth
        self.sessions += 1
        self._undo, self._after_move = [], []
        cell: Cell = session.cell
        move, measure, stop = cell.move_to, cell.measure_force_n, cell.stop
        zero, check_zero = cell.zero_in_free_space, cell.check_zero
        zeroing = [False]

        def zero_in_free_space() -> float:
            zeroing[0] = True  # its burst reads the bias it is about to zero: not judged
            try:
                return zero()
            finally:
                zeroing[0] = False

        def checked_zero(bound_n: Any) -> tuple[float, float]:
            zeroing[0] = True  # the zero check's burst judges the zero, not a force
            tares = cell.tares
            try:
                return check_zero(bound_n)
            finally:
                zeroing[0] = False
                if cell.tares > tares:  # accepted: its burst's mean is the zero (in software)
                    truth.zeroed_in_software()

        def move_to(pose: Any, settle: bool = True) -> None:
            self._step()
            try:
                move(pose, settle)
            finally:  # a fault of one move ends with it
                undo, self._after_move = self._after_move, []
                for action in undo:
                    action()

        def measure_force_n(samples: int | None = None) -> float:
            self._step()
            self.reads.append(self._mark())
            truth.begin_burst()
            force = measure(samples)
            if samples is None and not zeroing[0]:  # a whole burst: what a step is judged by
                truth.judge_reading(force, self._last)
            return force

        def stopped() -> None:
            self.stops.append(self._mark())
            stop()

        reinitialise = getattr(session.sensor, "reinitialise", None)
        if reinitialise is not None:  # the recovery's sensor restarts count as instants too

            def restarted() -> None:
                self._step()
                self.reads.append(self._mark())
                reinitialise()

            session.sensor.reinitialise = restarted

        cell.move_to = move_to  # type: ignore[method-assign]
        cell.measure_force_n = measure_force_n  # type: ignore[method-assign]
        cell.stop = stopped  # type: ignore[method-assign]
        cell.zero_in_free_space = zero_in_free_space  # type: ignore[method-assign]
        cell.check_zero = checked_zero  # type: ignore[method-assign]

    def _mark(self) -> Mark:
        return Mark(self.tick, self.sessions, self.session.cell.time_s, time.perf_counter())

    def _step(self) -> None:
        self.tick += 1
        for due, undo in [u for u in self._undo if u[0] <= self.tick]:
            self._undo.remove((due, undo))
            undo()
        for device, kind in self.plan.pop(self.tick, []):
            self._fire(device, kind)

    def _fire(self, device: str, kind: str) -> None:
        cell = self.session.cell
        assert self.truth is not None
        self.fired.append(Fired(device, kind, self.tick, cell.time_s, self.events(),
                                self.sessions, self.truth.contact_n() > 0.0))
        self._last = kind
        if kind == "kill":
            raise Killed
        getattr(self, f"_{device}_{kind}")()

    # ---- sensor faults ---------------------------------------------------------------------
    def _sensor_reboot(self) -> None:
        emulator = self.session.sensor_emulator
        (emulator.inject_bootup if hasattr(emulator, "inject_bootup") else emulator.inject_reboot)()

    def _sensor_silence(self) -> None:
        emulator = self.session.sensor_emulator
        emulator.set_faults(dataclasses.replace(emulator.faults, silent=True))
        self._undo.append((self.tick + self.rng.randint(1, 3), lambda: emulator.set_faults(
            dataclasses.replace(emulator.faults, silent=False))))

    def _sensor_corrupt(self) -> None:
        emulator, count = self.session.sensor_emulator, self.rng.randint(2, 12)
        if hasattr(emulator, "frame_hook"):  # JR3: frames of a wrong length
            left = [count]

            def garble(frame: Frame) -> Frame | None:
                if left[0] <= 0:
                    return frame
                left[0] -= 1
                size = (len(frame.data) + 1 + self.rng.randint(0, 6)) % 9
                return Frame(frame.arbitration_id, (frame.data + bytes(8))[:size])

            emulator.frame_hook = garble
            return
        self._netft_corrupt(emulator, count)

    def _netft_corrupt(self, emulator: Any, count: int) -> None:
        """Net F/T: the next ``count`` datagrams the box sends the driver arrive damaged.

        What an RDT client can receive (UDP's checksum drops a datagram damaged on the
        wire, so damage that arrives is the box's or a stack's): a datagram cut short
        or run long (not a whole number of 36-byte records), a record whose status
        word has the box's error bit set (its counts then mean nothing), or 36 bytes
        of garbage (random sequences, status and counts). They replace the box's own
        datagrams in the driver's stream, as they would on the wire; without the
        in-process route (UDP), the records carry the error status instead.
        """
        address = getattr(self.session.sensor._sock, "address", None)
        deliver = emulator._local.get(address) if address is not None else None
        left = [count]
        if deliver is None:  # over UDP: the box flags its records

            def flagged(records: list[Any]) -> list[Any]:
                out = []
                for record in records:
                    if left[0] > 0:
                        left[0] -= 1
                        record = dataclasses.replace(record, status=RDT_ERROR_STATUS)
                    out.append(record)
                if left[0] <= 0:
                    emulator.records_hook = None
                return out

            emulator.records_hook = flagged
            return

        def damaged(data: bytes) -> None:
            if left[0] > 0:
                left[0] -= 1
                data = self._damage_rdt(data)
                if left[0] == 0:
                    emulator._local[address] = deliver
            deliver(data)

        emulator._local[address] = damaged

    def _damage_rdt(self, data: bytes) -> bytes:
        """One RDT datagram as it may arrive damaged (:meth:`_netft_corrupt`)."""
        kind = self.rng.choice(("short", "long", "status", "garbage"))
        if kind == "short":
            return data[:self.rng.randint(0, RDT_RECORD_SIZE - 1)]
        if kind == "long":
            return data + self.rng.randbytes(self.rng.randint(1, RDT_RECORD_SIZE - 1))
        if kind == "status":  # the first record's status word (offset 8, u32) with the error bit
            status = RDT_ERROR_STATUS | self.rng.randrange(1 << 16)
            return data[:8] + status.to_bytes(4, "big") + data[12:]
        return self.rng.randbytes(RDT_RECORD_SIZE)

    def _sensor_bias_jump(self) -> None:
        jump = self.rng.choice((-1.0, 1.0)) * self.rng.uniform(1.0, 8.0)  # on the bias's axis
        shift_sensor_bias(self.session, self.session.cell.force_filter.config.sign * jump)
        assert self.truth is not None
        self.truth.jumped = True

    # ---- robot faults ----------------------------------------------------------------------
    def _robot_restart(self) -> None:
        emulator = self.session.robot_emulator
        if isinstance(getattr(emulator, "faults", None), EgmFaultInjector):
            self._egm_faults(EgmFaultConfig(restart=Fault(1.0, limit=1)))
            return
        self._robot_stall(fraction=0.0)
        hang_up = ComputerLinkFaultConfig(drop_connection=Fault(1.0, limit=1))
        emulator.faults = FaultInjector(hang_up)

    def _robot_stall(self, fraction: float | None = None) -> None:
        emulator = self.session.robot_emulator
        share = self.rng.uniform(0.2, 0.8) if fraction is None else fraction
        engine = getattr(emulator, "engine", None)
        if engine is not None:  # the computer link's controller: its arm motion
            engine.motion.stall_fraction = share
            self._after_move.append(lambda: setattr(engine.motion, "stall_fraction", None))
            return
        motion = emulator.model.motion  # EGM: the servo ignores commands for this move
        motion.command = lambda pose, t_s: None
        self._after_move.append(lambda: motion.__dict__.pop("command", None))

    def _robot_link_drop(self) -> None:
        emulator = self.session.robot_emulator
        if isinstance(getattr(emulator, "faults", None), EgmFaultInjector):
            lost = (self.rng.randint(EGM_LOST_MAX + 1, EGM_LONG_LOST_MAX)
                    if self.rng.random() < EGM_LONG_SHARE else self.rng.randint(1, EGM_LOST_MAX))
            if lost > EGM_LOST_MAX:  # past the CommTimeout: counted as its own kind
                self.fired[-1].kind = "long_link_drop"
            self._egm_faults(EgmFaultConfig(lose=Fault(1.0, limit=lost)))
            return
        hang_up = ComputerLinkFaultConfig(drop_connection=Fault(1.0, limit=1))
        emulator.faults = FaultInjector(hang_up)

    def _egm_faults(self, faults: EgmFaultConfig) -> None:
        emulator = self.session.robot_emulator
        injector = EgmFaultInjector(faults)
        injector.cycle = emulator.faults.cycle
        emulator.faults = emulator.loop.faults = injector


CAUSES: dict[str, tuple[str, ...]] = {
    "SensorRebooted": ("reboot",),
    "SensorSuspect": ("bias_jump", "reboot"),
    "ZeroMoved": ("bias_jump", "reboot"),
    "SensorStale": ("silence", "corrupt"),
    "SensorTimeout": ("silence", "corrupt", "reboot"),
    "SensorBusError": ("corrupt",),
    "SensorProtocolError": ("corrupt",),
    "NotInPosition": ("stall", "restart"),
    "GuidanceStopped": ("restart", "long_link_drop"),
    "LinkTimeout": ("link_drop", "long_link_drop", "restart"),
    "LinkError": ("link_drop", "long_link_drop", "restart"),
    "ProtocolError": ("link_drop", "long_link_drop", "restart"),
}
"""The fault kinds that can raise each error (to say which fault a recovery recovered from)."""


def cause(error: str, fired: list[Fired], events_before: int) -> Fired | None:
    """The fault a recovery (the run's event number ``events_before``) recovered from."""
    before = [f for f in fired if f.events_before <= events_before]
    kinds = CAUSES.get(error)
    matching = [f for f in before if kinds is None or f.kind in kinds] or before
    return matching[-1] if matching else None


def plan_faults(rng: random.Random, ticks: int, counts: dict[tuple[str, str], int]
                ) -> dict[int, list[tuple[str, str]]]:
    """Spread ``counts[(device, kind)]`` faults over ticks 1..``ticks`` at random instants."""
    plan: dict[int, list[tuple[str, str]]] = {}
    for (device, kind), count in counts.items():
        for _ in range(count):
            plan.setdefault(rng.randint(1, max(1, ticks)), []).append((device, kind))
    return plan


def stop_latency_s(fired: Fired, stops: list[Mark]) -> float | None:
    """Cell time from a fault to the first robot stop after it in its session (None: none)."""
    for stop in stops:
        if (stop.session == fired.session and stop.tick >= fired.tick
                and stop.cell_time_s >= fired.cell_time_s):
            return stop.cell_time_s - fired.cell_time_s
    return None


def read_to_stop_s(fired: Fired, stops: list[Mark], reads: list[Mark]
                   ) -> tuple[float | None, float]:
    """(wall s from the first read after a sensor fault to the stop, cell s the fault went unread).

    The cell consults the sensor only when it reads: a fault during a move is
    found at the next read, which stops the robot within the driver's watchdog
    (no cell time passes during a read, so that part is wall time). A robot
    stopped before that read gives 0; no stop at all, None.
    """
    first = next((r for r in reads if r.session == fired.session and r.tick >= fired.tick), None)
    stop = next((s for s in stops if s.session == fired.session and s.tick >= fired.tick), None)
    if stop is None:
        return None, 0.0
    if first is None or stop.tick < first.tick:
        return 0.0, max(0.0, stop.cell_time_s - fired.cell_time_s)
    return max(0.0, stop.wall_s - first.wall_s), max(0.0, first.cell_time_s - fired.cell_time_s)


def finite(value: float) -> bool:
    """True for a finite float."""
    return math.isfinite(value)
