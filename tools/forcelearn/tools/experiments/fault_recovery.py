"""A run that meets a device fault: leave the part, re-zero, and go on with the trial.

The run engine calls :meth:`RunRecovery.train` instead of training directly,
:meth:`RunRecovery.probe` around the surface probe, :meth:`RunRecovery.on_exit`
when the run stops on an error or Ctrl-C, and :meth:`RunRecovery.on_resume`
right after a resumed run opened its cell. After a device fault
(:func:`forcelearn.tasks.recovery.recoverable`: a sensor that rebooted, went
silent or sent damage, a controller restart, a dropped link, a move that never
reached its target) during a trial:

1. the robot is stopped; the trial is rolled back to the last checkpoint
   (results, records of the unfinished trial, the map's wear state, and the
   learner: read back from the checkpoint, or the start's copy before the first);
2. the tool retracts along the force axis and the sensor is started again and
   zeroed in free space (:func:`~forcelearn.tasks.recovery.retract_and_retare`,
   the calibration's bias re-derived);
3. the trial runs again; the re-zero is its first tare record.

During the trials a :class:`~forcelearn.tasks.bias_watch.BiasWatch` judges
every step's reading by the move that led to it: a reading the foam's
stiffness cannot explain (a bias step in contact) raises
:class:`~forcelearn.errors.SensorSuspect` and is recovered from the same way;
the free-space reading before the re-zero is the zero check (its event says
how far the zero had moved). A fault-free run never trips it, so it changes
nothing there.

A bias step the watch cannot see (smaller than its margin, or in free space
before a trial's first press) would leave the trial's readings off by the step.
With ``[task] zero_check`` every trial is a transaction: at its end, before
its checkpoint, the tool reads free space at the retract plane
(:meth:`~forcelearn.cell.Cell.check_zero`); off zero by more than
:data:`ZERO_CHECK_SIGMAS` x what a fault-free check reads
(:func:`~forcelearn.tasks.zero_check.zero_check_bound`: the burst's and the zero's noise,
the bias's drift since the zero), the zero moved during the trial, which is void
(:class:`~forcelearn.errors.ZeroMoved`): rolled back as after a fault, re-zeroed in free
space and run again. The same check closes the surface probe (which then starts over).
What a rolled-back trial or probe had recorded is kept in ``voided.jsonl``, never in
``records.mcap`` or ``trials.csv``: nothing is lost and nothing counted twice.

Every fault is one line of ``faults.jsonl`` in the run directory (what, when,
what was lost, what the cell did) and counted in ``summary.json`` (``faults``).
A trial that faults ``MAX_TRIES_PER_TRIAL`` times, or a recovery that fails,
ends the run with that typed error; the event says so and whether the tool may
still be in contact, and the file ``IN_CONTACT`` then tells ``--resume`` to
retract before anything else.
"""

from __future__ import annotations

import contextlib
import copy
import dataclasses
import json
import logging
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any, TypeVar

from forcelearn.cell import Cell
from forcelearn.devices import Pose
from forcelearn.errors import ForcelearnError, SensorSuspect, ZeroMoved, one_line
from forcelearn.learning import SRVLearner, load_learner
from forcelearn.press_guard import PRESS_AGREE_N, PRESS_AGREE_SHARE, press_agreement_n
from forcelearn.tasks.bias_watch import CONTACT_N, BiasWatch
from forcelearn.tasks.recovery import AwayFrom, RecoveryFailed, recoverable, retract
from forcelearn.tasks.recovery import retract_and_retare as leave_and_rezero
from forcelearn.tasks.surface import SurfaceYOutput
from forcelearn.tasks.zero_check import ZERO_CHECK_SIGMAS, check_zero
from forcelearn.tools.experiments.records import step_to_json, tare_to_json

log = logging.getLogger(__name__)

EVENTS_FILE = "faults.jsonl"
VOIDED_FILE = "voided.jsonl"
IN_CONTACT_FILE = "IN_CONTACT"
FALSE_ALARM_WIDENING = 1.5
"""A bias-step alarm whose zero check finds the zero in place widens the watch's margins by
this and does not count as one of the trial's tries (a noisy or relaxing foam moves more between
steps than the margins measured on the example sponge; about ten such alarms make the watch
silent, so this ends)."""
MAX_TRIES_PER_TRIAL = 4
"""Faults one trial may meet before the run ends (each is recovered from before the next)."""

_T = TypeVar("_T")


@dataclasses.dataclass(frozen=True)
class FaultEvent:
    """One fault the run met, and what the cell did (a line of ``faults.jsonl``)."""

    trial: int
    """The trial it interrupted (-1: the surface probe, before the first trial)."""
    error: str
    """The typed error's class name (``SensorRebooted``, ``LinkTimeout``...)."""
    message: str
    """Its one-line message (what happened, what to check)."""
    action: str
    """``resumed`` (retracted, re-zeroed, trial run again), ``ended`` (the run stopped),
    ``voided`` (the zero check found the zero moved: the trial rolled back, re-zeroed, run
    again), ``interrupted`` (Ctrl-C), ``retracted on resume``."""
    lost: str = ""
    """What a rebooted sensor lost (offsets, software bias); empty otherwise."""
    retract_y_mm: float | None = None
    """Where the tool retracted to (None: it did not)."""
    free_reading_n: float | None = None
    """Free space's reading before the re-zero, N (None: no re-zero)."""
    in_contact: bool = False
    """True when the run ended and the tool may still press the part."""
    cell_time_s: float = 0.0
    """The cell's clock when the recovery ended, s."""


class RunRecovery:
    """The run's side of faults (the module docstring).

    Args:
        out: the run directory.
        cell: the open cell.
        retract_y_mm: the retract plane (``[task] retract_y_mm``), free space.
        max_step_mm: the step limit (``[safety] max_step_mm``).
        output: the learner's output map (its wear state is rolled back with the trial).
        checkpoint: the run's checkpoint file (the learner is read back from it).
        zero_check: read free space at each trial's (and the probe's) end
            (``[task] zero_check``; :meth:`check_zero`).
        away: where to retract to from where the tool is (the path task: back along its
            force axis); None: +Y to ``retract_y_mm``.
        watch: judge the readings by the moves (:class:`BiasWatch`, made for the §5 task's
            moves along Y); False: faults only.
    """

    def __init__(self, out: Path, cell: Cell, retract_y_mm: float, max_step_mm: float,
                 output: SurfaceYOutput | None = None, checkpoint: Path | None = None,
                 zero_check: bool = False, away: AwayFrom | None = None,
                 watch: bool = True) -> None:
        self.out, self.cell = out, cell
        self.zero_check = zero_check
        self.retract_y_mm, self.max_step_mm = retract_y_mm, max_step_mm
        self.output = output
        self.checkpoint = checkpoint
        self.away = away
        self.watching = watch
        self.events: list[FaultEvent] = []
        """The faults of this session."""
        self.watch = BiasWatch(free_y_mm=retract_y_mm)
        """Judges the trials' readings by the moves (bias steps in contact)."""
        self._checked_zeros = 0
        """Zeros the zero check took (within its bound: they keep a first press comparable with
        the last trial's, which a bias step at the first contact would not be)."""
        self._referenced = False
        """The first press's reference when the cell has no press guard to keep it."""
        self.trial = -1
        """The trial running (for the messages), -1: none yet."""
        self.fit_watch_to_readings = True
        """Widen the watch to the stiffness the readings show (until a probe's fit is in)."""
        self._start_learner: SRVLearner | None = None

    # ---- the run's calls -------------------------------------------------------------------
    def train(self, learner: SRVLearner, run: Any,
              train_remaining: Callable[[SRVLearner, int], object]) -> SRVLearner:
        """Run the remaining trials, recovering from device faults; return the learner in use.

        ``run`` is the :class:`SurfaceRun` (its ``trials``, ``result``, ``saved`` and
        ``rollback_to_saved``); ``train_remaining(learner, n)`` runs ``n`` trials.
        """
        if run.saved.trials == 0:
            self._start_learner = _copy_learner(learner)
        tries: dict[int, int] = {}
        with self._watching():
            while (remaining := run.trials - len(run.result.records)) > 0:
                self.trial = run.saved.trials
                try:
                    train_remaining(learner, remaining)
                    break
                except ForcelearnError as exc:
                    if not recoverable(exc):
                        raise
                    trial = run.saved.trials
                    tries[trial] = tries.get(trial, 0) + 1
                    run.rollback_to_saved()
                    self._restore_map(run)
                    self._void(trial, exc)
                    if self._recover(exc, trial, tries[trial]):  # a false bias-step alarm
                        tries[trial] -= 1
                    learner = self._saved_learner(run, learner)
        return learner

    def probe(self, probe: Callable[[], _T]) -> _T:
        """Run the surface probe, recovering from device faults (the probe starts over)."""
        for attempt in range(1, MAX_TRIES_PER_TRIAL + 1):
            try:
                with self._watching():
                    found = probe()
                    self.check_zero(-1)
                    return found
            except ForcelearnError as exc:
                if not recoverable(exc):
                    raise
                self._void(-1, exc)
                self._recover(exc, -1, attempt)
        raise AssertionError("unreachable")  # pragma: no cover - _recover raises at the last try

    @property
    def referenced(self) -> bool:
        """A trial's first press has an earlier trusted one to be compared with.

        None at a session's start nor after a re-zero in free space (:meth:`press_in` makes
        it twice). Kept by the cell's press guard (checkpointed with it: an emulated resume,
        whose sensor keeps its zero, goes on as the uninterrupted run did; a real one starts
        afresh).
        """
        guard = self.cell.press_guard
        return self._referenced if guard is None else guard.referenced

    @referenced.setter
    def referenced(self, value: bool) -> None:
        guard = self.cell.press_guard
        if guard is None:
            self._referenced = value
        else:
            guard.referenced = value

    def press_in(self, press: Callable[[], float]) -> float:
        """A trial's first press (``press``: move in from free space, read; N): the force, N.

        With the zero check on, a first press that has no earlier trusted one to be
        compared with (the session's first, the first after a re-zero) is made twice,
        each from a zero checked in free space right before it: check, press, back out to
        free space, check, press again. A bias step during the first press is then seen
        by the second check, one during the second by the two presses' disagreement
        (beyond :func:`~forcelearn.press_guard.press_agreement_n` of the first), before
        any step of the trial presses deeper on a wrong reading; a drift since the
        session's zero is zeroed away before the first contact.

        Raises:
            ZeroMoved: a check found the zero moved.
            SensorSuspect: the two presses disagree.
        """
        if self.referenced or not self.zero_check:
            return press()
        self.check_zero(self.trial)
        first = press()
        self.check_zero(self.trial)  # backs out to the retract plane first
        second = press()
        if abs(second - first) > press_agreement_n(first):
            self.cell.stop()
            raise SensorSuspect(
                f"trial {self.trial}'s first press read {first:.2f} N, then {second:.2f} N "
                f"pressed again at the same place from a zero checked in free space (more "
                f"than {PRESS_AGREE_N:g} N + {100 * PRESS_AGREE_SHARE:g} % apart): the "
                "sensor's zero moved during the second press (a bias step at the first "
                "contact); the run retracts, zeroes in free space and runs the trial again"
            )
        self.referenced = True
        return second

    def refresh_zero(self) -> None:
        """Before a press near the limit on a stale zero: retract, check the zero, press back.

        The cell's :attr:`~forcelearn.cell.Cell.refresh_zero` (the §5 task presses along -Y):
        up to the retract plane, the zero check (:meth:`check_zero`: within its bound the
        zero there; beyond it :class:`~forcelearn.errors.ZeroMoved`, the trial void), down
        again to where the tool was, guarded, and one reading there. The cut press then goes
        on from a zero a moment old: a drift no check had seen is measured or bounded.
        """
        cell = self.cell
        here, stage = cell.pose, cell.stage
        self.check_zero(self.trial)
        cell.stage = stage
        cell.move_in_steps(here, self.max_step_mm, guard_force=True)
        cell.measure_force_n(1)

    def on_exit(self, exc: BaseException, trial: int) -> None:
        """The run stops (an error it does not recover from, or Ctrl-C): leave the part first.

        A second Ctrl-C during the retract stops it; the tool may then still be in
        contact, which the log, ``faults.jsonl`` and ``IN_CONTACT`` say.
        """
        interrupted = isinstance(exc, KeyboardInterrupt)
        in_contact = bool(getattr(exc, "in_contact", False))
        retract_y: float | None = None
        if interrupted or not isinstance(exc, RecoveryFailed):
            try:
                pose, _ = retract(self.cell, self.retract_y_mm, self.max_step_mm, attempts=1,
                                  away=self.away)
                retract_y, in_contact = pose.y_mm, False
            except KeyboardInterrupt:
                self.cell.stop()
                in_contact = True
                log.error("second Ctrl-C: the retract was stopped; the tool may still press "
                          "the part at %s", self.cell.known_pose)
            except ForcelearnError as failed:
                in_contact = True
                log.error("could not retract before stopping: %s", one_line(failed))
        message = "Ctrl-C" if interrupted else one_line(exc)
        if in_contact:
            message += ("; the tool may still press the part: retract it by hand, or resume "
                        "the run (it retracts first)")
        self._event(FaultEvent(
            trial, type(exc).__name__, message, "interrupted" if interrupted else "ended",
            lost=str(getattr(exc, "lost", "")), retract_y_mm=retract_y, in_contact=in_contact,
            cell_time_s=self.cell.time_s,
        ))
        if in_contact:
            (self.out / IN_CONTACT_FILE).write_text(json.dumps({"error": type(exc).__name__}))

    def on_resume(self) -> None:
        """A resumed run whose last session stopped in contact retracts and re-zeroes first."""
        marker = self.out / IN_CONTACT_FILE
        if not marker.exists():
            return
        recovered = leave_and_rezero(self.cell, self.retract_y_mm, self.max_step_mm,
                                     away=self.away)
        self._event(FaultEvent(
            -1, "StoppedInContact", "the last session stopped with the tool in contact",
            "retracted on resume", retract_y_mm=recovered.retract_pose.y_mm,
            free_reading_n=recovered.free_reading_n, cell_time_s=self.cell.time_s,
        ))
        marker.unlink()

    def check_zero(self, trial: int) -> None:
        """The zero check closing a trial (-1: the probe): free space must read the zero.

        Called before the trial's checkpoint. The tool goes up to the retract plane
        if it is not there (a trial ends there), reads one burst and, within
        :func:`~forcelearn.tasks.zero_check.check_zero`'s bound (read twice before it
        fails), zeroes there (the next trial's baseline).

        Raises:
            ZeroMoved: the reading is beyond the bound: the trial's readings are void.
        """
        if not self.zero_check:
            return
        cell = self.cell
        here = cell.pose
        if here.y_mm < self.retract_y_mm:
            cell.move_in_steps(Pose(here.x_mm, self.retract_y_mm, here.z_mm, here.quaternion),
                               self.max_step_mm)
        force, bound = check_zero(cell)
        self._checked_zeros += abs(force) <= bound
        if abs(force) > bound:
            cell.stop()
            what = "the probe (or the session's start)" if trial < 0 else f"trial {trial}"
            raise ZeroMoved(
                f"the zero check after {what} read {force:.2f} N in free space, more than "
                f"{bound:.2f} N from 0 ({ZERO_CHECK_SIGMAS:g} sigma of a check's noise and the "
                "bias's drift since the last zero): the "
                f"zero moved during {what}, whose readings are void; the run re-zeroes in free "
                "space and runs it again (if it repeats, check the sensor's cable and temperature)"
            )

    def probe_zero_check(self) -> None:
        """The zero check at each probe point's start (in free space; the probe's, -1)."""
        self.check_zero(-1)

    # ---- inside ------------------------------------------------------------------------------
    @contextlib.contextmanager
    def _watching(self) -> Iterator[None]:
        """The bias watch judges the readings inside (unless the run does not watch)."""
        if not self.watching:
            yield
            return
        self.cell.reading_check = self._check
        try:
            yield
        finally:
            self.cell.reading_check = None

    def _check(self, stage: tuple[str, int], pose: Pose | None, force_n: float) -> None:
        """The cell's reading check: a frozen burst, then the bias watch (told the zeros).

        Without a probe's fit the watch widens to the stiffest rise the cell's press guard
        has seen, or its first contact's (a stiff part met cold: its ease-offs drop faster
        than the default band).
        """
        if self.cell.burst_frozen:
            raise SensorSuspect(
                f"every sample of the burst at {stage[0]} {stage[1]} read the very same wrench: "
                "a live sensor's noise never repeats exactly, so the sensor (or its link) "
                "repeats one reading; the run retracts, restarts and zeroes the sensor in free "
                "space and runs the trial again; if it repeats, check the sensor and its cable"
            )
        guard = self.cell.press_guard
        if self.fit_watch_to_readings and guard is not None:
            seen = max(guard.observed_n_per_mm or 0.0, guard.first_contact_n_per_mm or 0.0)
            if seen > 0.0:  # the steepest rise in contact, or the first contact's (a stiff part
                self.watch.fit_to_probe([seen], 0.0, 0.0)  # met in one move shows no pair)
        self.watch(stage, pose, force_n, zeros=self.cell.tares - self._checked_zeros)

    def _recover(self, exc: ForcelearnError, trial: int, attempt: int) -> bool:
        """Leave the part and re-zero; True: a bias-step alarm the zero check proved false."""
        lost = str(getattr(exc, "lost", ""))
        if attempt > MAX_TRIES_PER_TRIAL - 1:
            exc.add_note(f"trial {trial} met {attempt} faults; the run stops")
            raise exc
        log.warning("trial %d: %s: %s; retracting and re-zeroing", trial, type(exc).__name__,
                    one_line(exc))
        check, self.cell.reading_check = self.cell.reading_check, None  # the zero check reads
        try:
            recovered = leave_and_rezero(self.cell, self.retract_y_mm, self.max_step_mm,
                                         away=self.away)
        except RecoveryFailed as failed:
            failed.add_note(f"after {type(exc).__name__}: {one_line(exc)}")
            raise
        finally:
            self.cell.reading_check = check
        self.referenced = False  # re-zeroed: the next first press has nothing to compare with
        message = one_line(exc)
        false_alarm = False
        action = "resumed"
        if isinstance(exc, ZeroMoved):
            action = "voided"
            message += f"; re-zeroed (free space read {recovered.free_reading_n:.2f} N)"
        elif isinstance(exc, SensorSuspect):  # the free-space reading is the zero check
            moved = abs(recovered.free_reading_n) > CONTACT_N
            false_alarm = not moved and trial >= 0
            if false_alarm:  # this material moves more than the watch allowed
                self.watch.widen(FALSE_ALARM_WIDENING)
            message += (f"; zero check: free space read {recovered.free_reading_n:.2f} N, "
                        + ("the zero had moved (re-tared)" if moved
                           else "the zero had not moved (a false alarm: the watch's margins "
                                f"widened x{FALSE_ALARM_WIDENING:g} to "
                                f"{self.watch.margin_n:.2f} N; the trial runs again)" if false_alarm
                           else "the zero had not moved (a false alarm, or a force change)"))
        self._event(FaultEvent(
            trial, type(exc).__name__, message, action, lost=lost,
            retract_y_mm=recovered.retract_pose.y_mm, free_reading_n=recovered.free_reading_n,
            cell_time_s=self.cell.time_s,
        ))
        return false_alarm

    def _void(self, trial: int, exc: ForcelearnError) -> None:
        """Set aside what a rolled-back trial (-1: the probe) recorded: a line of voided.jsonl."""
        self.watch.forget()
        recorder = self.cell.recorder
        take = getattr(recorder, "take", None)
        if take is None:
            return
        records = take(trial)
        if not records.steps and not records.tares:
            return
        line = {"trial": trial, "error": type(exc).__name__,
                "steps": [step_to_json(step) for step in records.steps],
                "tares": [tare_to_json(tare) for tare in records.tares]}
        with open(self.out / VOIDED_FILE, "a") as handle:
            handle.write(json.dumps(line) + "\n")

    def _restore_map(self, run: Any) -> None:
        """The output map's wear state as of the checkpoint (a trial's press moved it)."""
        if self.output is not None:
            self.output.shift_mm = run.map_shift_mm
            self.output.recentre_mm = run.map_recentre_mm
            self.output.wear_reference_n = run.wear_reference_n

    def _saved_learner(self, run: Any, learner: SRVLearner) -> SRVLearner:
        """The learner as the checkpoint holds it (or as it started, before any checkpoint)."""
        if run.saved.trials == 0 and self._start_learner is not None:
            return _copy_learner(self._start_learner)
        assert self.checkpoint is not None
        return load_learner(self.checkpoint, output=learner.output)[0]

    def _event(self, event: FaultEvent) -> None:
        self.events.append(event)
        with open(self.out / EVENTS_FILE, "a") as handle:
            handle.write(json.dumps(dataclasses.asdict(event)) + "\n")
            handle.flush()


def _copy_learner(learner: SRVLearner) -> SRVLearner:
    """A deep copy that shares the output map (the task and the learner use one object)."""
    return copy.deepcopy(learner, memo={id(learner.output): learner.output})


def read_events(out: Path) -> list[dict[str, Any]]:
    """The run's fault events from ``faults.jsonl`` (a torn last line is skipped)."""
    path = out / EVENTS_FILE
    if not path.exists():
        return []
    events = []
    for line in path.read_text().splitlines():
        with contextlib.suppress(json.JSONDecodeError):
            events.append(json.loads(line))
    return events


def fault_summary(out: Path) -> dict[str, Any]:
    """``summary.json``'s ``faults``: counts by error and action, and how the run ended."""
    events = read_events(out)
    by_error: dict[str, int] = {}
    for event in events:
        by_error[event["error"]] = by_error.get(event["error"], 0) + 1
    ended = [e for e in events if e["action"] in ("ended", "interrupted")]
    return {
        "count": len(events),
        "resumed": sum(e["action"] == "resumed" for e in events),
        "voided": sum(e["action"] == "voided" for e in events),
        "by_error": by_error,
        "last_stop": ended[-1] if ended else None,
        "in_contact": (out / IN_CONTACT_FILE).exists(),
    }
