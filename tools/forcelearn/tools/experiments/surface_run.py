"""Paper §5 on a cell: the trial loop, with a checkpoint after every trial, and resume.

The run's state and its checkpoint are :mod:`.surface_state`'s, the files it
writes at the end :mod:`.surface_outputs`'; docs/run-directory.md is the run
directory's contract. :func:`forcelearn.runs.run_surface` is the front door.

A new run first probes the surface (:mod:`forcelearn.tasks.surface_probe`)
and takes its output map from the fit; the probe and the map are kept in the
checkpoint, so a resumed run does not probe again. The learner starts from the
probe's path (``[run] learner_start = "probe"``) or from μ = 0 (``"cold"``,
:mod:`forcelearn.tasks.surface_warm_start`). During the run a
:class:`~forcelearn.tasks.surface_diagnosis.StuckMonitor` warns (once, through
``on_warning`` and the log) when learning is stuck, and
:func:`~forcelearn.tasks.surface_feasibility.assess` when the run's own
estimates say the desired force is out of reach after wear.

Every trial's records (``records.mcap``) are made durable before its
checkpoint. A resumed run re-opens the cell, restores the learner (with its
random generator) and, on an emulated cell, the emulators' state, then
continues with the next trial: it ends bit-identical to an uninterrupted run
with the same seed.
"""

from __future__ import annotations

import contextlib
import logging
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

from forcelearn.errors import ForcelearnError
from forcelearn.learning import SRVLearner, load_learner
from forcelearn.press_guard import PressGuard
from forcelearn.records import TrialRecords
from forcelearn.site.session import CellSession
from forcelearn.tasks.surface import SurfaceTask, TrialTrace
from forcelearn.tasks.surface_diagnosis import StuckMonitor
from forcelearn.tasks.surface_feasibility import FEASIBILITY_WINDOW, Feasibility, assess
from forcelearn.tasks.surface_map import SurfaceYOutput, allowed_bottom_y_mm, step_centre_y_mm
from forcelearn.tasks.surface_probe import SurfaceProbe, probe_and_map
from forcelearn.tasks.surface_warm_start import warm_start
from forcelearn.tools.experiments.fault_recovery import RunRecovery
from forcelearn.tools.experiments.records import (
    PROBE_TRIAL,
    RECORDS_FILE,
    RecordsWriter,
    scan_records,
)
from forcelearn.tools.experiments.run_recorder import TrialRecorder
from forcelearn.tools.experiments.surface_outputs import write_outputs, write_probe_files
from forcelearn.tools.experiments.surface_state import (
    CHECKPOINT,
    SurfaceRun,
    load_checkpoint,
    save_checkpoint,
)
from forcelearn.trainer import (
    CONVERGENCE_TOLERANCE,
    StepHook,
    TrialLog,
    TrialRecord,
    converged_trial,
    train,
)

log = logging.getLogger(__name__)


class _ConvergedStop(Exception):
    """Raised after a trial to end a run early (``[run] stop_after_converged``)."""


def execute(
    run: SurfaceRun,
    checkpoint: Path | None,
    on_trial: Callable[[TrialRecord, SRVLearner], Any] | None = None,
    on_warning: Callable[[str], Any] | None = None,
    on_step: StepHook | None = None,
) -> dict[str, Any]:
    """Open the cell and run (or continue) the trials; checkpoint after each; return the summary.

    A new run probes the surface first (unless ``[probe] enabled = false`` or
    the config gives the whole output map); ``on_warning`` receives the stuck
    monitor's warnings (one line each); ``on_step`` sees every step's log row
    as it is made (``forcelearn run --live``).

    A device fault during the probe or a trial is recovered from
    (:mod:`~forcelearn.tools.experiments.fault_recovery`: retract, re-zero in
    free space, the trial again). Ctrl-C or an error the run does not recover
    from stops the robot and retracts it (a second Ctrl-C stops the retract and
    says so); the last whole trial is already on disk, and the outputs are
    written for the trials done before the exception propagates.
    """
    config = run.config
    started = time.perf_counter()
    wall_before = run.wall_s
    with CellSession(config, seed=run.seed) as session, contextlib.ExitStack() as stack:
        assert session.cell is not None
        guard = session.cell.press_guard = PressGuard(
            config.safety.max_force_n, config.task.press_stiffness_n_per_mm,
            session.cell.force_filter.measurement_variance_n2 ** 0.5)
        if checkpoint is not None:
            session.load_emulator_state(load_checkpoint(run, checkpoint))
        writer = records_writer(run, checkpoint is not None)
        stack.callback(writer.close)
        recorder = TrialRecorder(session.cell)
        recovery = RunRecovery(run.out, session.cell, config.task.retract_y_mm,
                               config.safety.max_step_mm, checkpoint=run.out / CHECKPOINT,
                               zero_check=config.task.zero_check)
        if config.task.zero_check:  # a press near the limit on a stale zero: check it first
            session.cell.refresh_zero = recovery.refresh_zero
        if checkpoint is not None:
            try:  # a session that stopped in contact: retract and re-zero first
                recovery.on_resume()
            except (KeyboardInterrupt, ForcelearnError) as exc:
                recovery.on_exit(exc, len(run.result.records))
                raise
        if checkpoint is None:
            session.cell.recorder = recorder
            try:
                recovery.probe(lambda: probe_and_choose(run, session, recovery.probe_zero_check))
            except (KeyboardInterrupt, ForcelearnError) as exc:
                recovery.on_exit(exc, -1)
                raise
            finally:
                session.cell.recorder = None
            probed = recorder.take(PROBE_TRIAL)
            if probed.steps:
                writer.write_trial(probed)
        assert run.output_map is not None
        step_mm = abs(config.task.z_step_mm)
        output = run.output_map.output(step_mm)
        output.shift_mm = run.map_shift_mm  # a resumed run's tracked wear
        output.recentre_mm = run.map_recentre_mm  # and its re-centring on the learner
        output.wear_reference_n = run.wear_reference_n
        task = SurfaceTask(session.cell, config.task, config.safety.max_step_mm, output)
        task.press_in = recovery.press_in  # a first press with no reference is made twice
        fit_watch_to_probe(recovery, run)
        if run.probe is not None and run.probe.fits:  # the part's stiffness is known
            guard.know(max(f.stiffness_n_per_mm for f in run.probe.fits))
        if checkpoint is not None:
            learner = load_learner(checkpoint, output=output)[0]
        else:
            learner = SRVLearner(task.grid, 1, config.learner, rng=run.seed, output=output)
            run.learner_start = start_learner(learner, run, output)
        monitor = run.monitor = StuckMonitor(
            run.output_map.centre_y_mm,
            run.output_map.max_offset_mm,
            config.task.steps_per_trial,
            path_y_mm=run.output_map.path_y_mm,
            source=run.output_map.source,
        )
        for record, trace in zip(run.result.records, run.traces, strict=True):  # resumed
            monitor.update(record, trace["command_y_mm"], trace["shift_mm"])
        trial_end = TrialEnd(
            run, session, output, writer, recorder,
            on_trial=on_trial, on_warning=on_warning, wall_clock=(wall_before, started),
            check=recovery.check_zero,
        )
        recovery.output = output
        try:  # a device fault: retract, re-zero, run the trial again (fault_recovery)
            learner = recovery.train(learner, run, lambda learner, remaining: train(
                learner,
                task,
                remaining,
                keep_logs=(run.mid_trial,),
                on_trial=trial_end,
                result=run.result,
                on_step=on_step,
            ))
        except _ConvergedStop:
            log.info("converged; stopped %d trials later", config.stop_after_converged)
        except (KeyboardInterrupt, ForcelearnError) as exc:
            session.cell.stop()
            run.rollback_to_saved()
            recovery.on_exit(exc, len(run.result.records))  # leaves the part first
            write_outputs(run, learner)
            raise
        finally:
            trial_end.close()
        task.retract()
    return write_outputs(run, learner)


def records_writer(run: SurfaceRun, resumed: bool) -> RecordsWriter:
    """Open the run's records.mcap: a new one, or a resumed run's rewound to its checkpoint.

    A resumed run keeps the whole trials its checkpoint holds (a file whose
    writer died is recovered up to its last whole trial) and drops later ones,
    which the run makes again. A run from before records existed starts one.
    """
    path = run.out / RECORDS_FILE
    kept: list[TrialRecords] = []
    if resumed and path.exists():
        done = len(run.result.records)
        kept = [t for t in scan_records(path).trials if t.trial < done]
    return RecordsWriter(path, kept)


class TrialEnd:
    """What the run does after each trial: trace, map, feasibility, records, checkpoint, hooks.

    Called by :func:`forcelearn.trainer.train` as its ``on_trial``. The trial's
    records are made durable before the checkpoint, so the records file never
    lacks a trial the checkpoint holds (a resume drops the extra one).

    Args:
        run: the run (its monitor set).
        session: the open cell session (its cell gets this trial's recorder).
        output: the learner's output map.
        writer: the run's records file.
        recorder: gathers each trial's records from the cell (set on it here).
        on_trial: called with each trial's record and the learner, after the checkpoint.
        on_warning: receives each warning's text.
        wall_clock: the run's wall time before this session (s) and the session's
            start (``time.perf_counter()``).
        check: called with the trial's index before anything is booked (the zero check,
            :meth:`RunRecovery.check_zero`: it raises to void the trial).
    """

    def __init__(
        self,
        run: SurfaceRun,
        session: CellSession,
        output: SurfaceYOutput,
        writer: RecordsWriter,
        recorder: TrialRecorder,
        on_trial: Callable[[TrialRecord, SRVLearner], Any] | None = None,
        on_warning: Callable[[str], Any] | None = None,
        wall_clock: tuple[float, float] = (0.0, 0.0),
        check: Callable[[int], None] | None = None,
    ) -> None:
        assert session.cell is not None and run.monitor is not None
        self.run, self.session, self.output = run, session, output
        self.cell = session.cell
        self.monitor = run.monitor
        self.feasibility_of = feasibility_check(run)
        self.on_trial, self.on_warning = on_trial, on_warning
        self.writer = writer
        self.recorder = recorder
        self.cell.recorder = recorder
        self._tares_before = run.tares
        self._wall_before, self._started = wall_clock
        self.check = check

    def __call__(self, record: TrialRecord, trial_log: TrialLog, learner: SRVLearner) -> None:
        """Book the trial that just ended (raises ``_ConvergedStop`` to end the run)."""
        if self.check is not None:
            self.check(record.index)
        run = self.run
        run.traces.append(self._trace(trial_log))
        run.wall_s = self._wall_before + time.perf_counter() - self._started
        self._follow_map(learner)
        new_finding = self._assess(record.index)
        cell, before = self.cell, self._tares_before
        run.tares = (before[0] + cell.tares, before[1] + cell.tares_refused)
        self.writer.write_trial(self.recorder.take(record.index))
        save_checkpoint(run, learner, self.session.emulator_state())
        warning = self.monitor.update(
            record, run.traces[-1]["command_y_mm"], run.traces[-1]["shift_mm"]
        )
        if new_finding and run.feasibility is not None:
            self._warn(run.feasibility.text())
        if warning is not None:
            self._warn(warning)
        if self.on_trial is not None:
            self.on_trial(record, learner)
        self._stop_if_converged(record)

    def _trace(self, trial_log: TrialLog) -> TrialTrace:
        output = self.output
        return TrialTrace(
            mean_y_mm=[
                output.command_at_step(row["mean_0"], int(row["step"]) - 1)
                for row in trial_log.rows
            ],
            command_y_mm=[row["command_0"] for row in trial_log.rows],
            shift_mm=output.displacement_mm,  # the range's move this trial ran with
            force_n=[row["force_n"] for row in trial_log.rows],
        )

    def _follow_map(self, learner: SRVLearner) -> None:
        """Re-centre the map on μ (before the save: μ and centre together) and keep it."""
        run, output = self.run, self.output
        output.recentre_on(learner.weights[..., 0])
        run.map_shift_mm = output.shift_mm
        run.map_recentre_mm = output.recentre_mm
        run.wear_reference_n = output.wear_reference_n

    def _assess(self, trial: int) -> bool:
        """Update the 'out of reach' estimate; True when this trial first found it."""
        run = self.run
        found = self.feasibility_of(trial)
        run.feasibility_now = found is not None
        if found is None:
            return False
        run.feasibility = found
        if run.feasibility_first_trial is None:
            run.feasibility_first_trial = trial
            return True
        return False

    def _warn(self, text: str) -> None:
        log.warning("%s", text)
        if self.on_warning is not None:
            self.on_warning(text)

    def _stop_if_converged(self, record: TrialRecord) -> None:
        config = self.run.config
        after = config.stop_after_converged
        if after > 0:
            at = converged_trial(
                self.run.result.records, config.task.steps_per_trial, config.task.desired_force_n
            )
            if at is not None and record.index - at >= after:
                raise _ConvergedStop

    def close(self) -> None:
        """Stop recording: forget a trial that did not end (the writer is the run's to close)."""
        self.cell.recorder = None
        self.recorder.discard()


def start_learner(learner: SRVLearner, run: SurfaceRun, output: Any) -> str:
    """Start a new run's learner as ``[run] learner_start`` says; return the start applied.

    The warm start needs the probe: without one (``[probe] enabled = false``,
    or the whole map configured) the learner starts cold, and the log says so.
    """
    if run.config.learner_start == "probe":
        if run.probe is not None and run.probe.fits:
            warm_start(learner, run.probe, run.config.task, output)
            return "probe"
        log.warning(
            "run.learner_start = \"probe\" needs the surface probe, which did not run "
            "([probe] enabled = false, or the whole output map is in [task]): the learner "
            "starts cold (mu = 0)"
        )
    return "cold"


def feasibility_check(run: SurfaceRun) -> Callable[[int], Feasibility | None]:
    """The run's 'is the force still in reach' test over its last trials (none without a probe)."""
    choice, probe, config = run.output_map, run.probe, run.config
    if choice is None or probe is None or not probe.fits:
        return lambda trial: None
    bottom = choice.allowed_bottom_y_mm
    if bottom is None:  # a checkpoint from before it was kept
        bottom = allowed_bottom_y_mm(probe, config.probe, config.safety.workspace_min_mm[1])
    task, half = config.task, choice.max_offset_mm
    k_probe = probe.stiffness_n_per_mm()
    contacts = probe.contact_path_mm(task).tolist()

    def check(trial: int) -> Feasibility | None:
        window = run.traces[-FEASIBILITY_WINDOW:]
        centres = [
            [step_centre_y_mm(choice.path_y_mm, choice.centre_y_mm, j) + t["shift_mm"]
             for j in range(len(t["command_y_mm"]))]
            for t in window
        ]
        return assess(
            [t["command_y_mm"] for t in window],
            [t["force_n"] for t in window],
            [[c - half for c in row] for row in centres],
            [[c + half for c in row] for row in centres],
            contacts,
            trial=trial,
            desired_force_n=task.desired_force_n,
            band_n=CONVERGENCE_TOLERANCE * task.desired_force_n,
            probe_stiffness_n_per_mm=k_probe,
            allowed_bottom_y_mm=bottom,
        )

    return check


def fit_watch_to_probe(recovery: RunRecovery, run: SurfaceRun) -> None:
    """Widen the bias-step watch to the material the probe measured (stiff parts, hysteresis)."""
    probe = run.probe
    if probe is None or not probe.fits:
        return
    recovery.fit_watch_to_readings = False
    hysteresis = probe.hysteresis()
    loss = hysteresis.loss + 2.0 * hysteresis.loss_std if hysteresis.resolved else 0.0
    recovery.watch.fit_to_probe([f.stiffness_n_per_mm for f in probe.fits], loss,
                                run.config.task.desired_force_n)


def probe_and_choose(run: SurfaceRun, session: CellSession,
                     zero_check: Callable[[], None] | None = None) -> None:
    """Probe the surface (if enabled and needed) and set the run's output map; write probe files.

    Raises:
        ProbeError: no surface found, or the desired force is out of reach.
    """
    config = run.config
    assert session.cell is not None
    probe = SurfaceProbe(
        session.cell,
        config.task,
        config.probe,
        config.safety.max_step_mm,
        config.safety.workspace_min_mm[1],
        zero_check,
    )
    try:
        run.probe, run.output_map = probe_and_map(
            probe, refine=config.learner_start == "probe"
        )
    except BaseException:
        if probe.result.rows:
            write_probe_files(run.out, probe.result, None)
        raise
    if run.probe is not None:
        write_probe_files(run.out, run.probe, run.output_map)


