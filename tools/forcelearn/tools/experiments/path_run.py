"""The path task on a cell: probe pass, warm start, passes learned, checkpoint and resume.

``forcelearn run`` comes here when the config's ``[task] kind = "path"`` or
``--path FILE`` is given (docs/path.md). The path is read and checked before
the cell opens (a refusal names the file, line or point); then, on the cell of
the config (any robot and sensor kind, emulated or real):

1. the probe pass (:mod:`forcelearn.tasks.path_probe`), which gives the
   stiffness, the output scale and the learner's warm start;
2. ``passes`` passes of the SRV learner over BOXES (the trainer's loop, the
   §5 task's learner and its generalized then specialized phases);
3. the run directory (:mod:`.path_outputs`): ``trials.csv``, ``passes.csv``,
   ``steps.csv``, ``probe.csv``, ``summary.json``, the figures and the end lines.

As the §5 run (:mod:`.surface_run`), with its machinery: each pass's moves,
bursts and tares go to ``records.mcap`` (:mod:`.records`, made durable first),
then the checkpoint (:mod:`.path_state`) is written atomically; a resumed run
(``forcelearn run --resume DIR``) restores the learner, the task and the
emulators and goes on with the next pass, ending as an uninterrupted run. A
device fault during the probe or a pass is recovered from by
:class:`~.fault_recovery.RunRecovery`: the tool retracts back along its force
axis (:meth:`~forcelearn.tasks.path.PathTask.away`), the sensor is re-zeroed in
free space and the pass runs again; a run that stopped in contact starts its
resume with that retract. ``on_step`` (``--live``, the journal) sees every
step's row.

Faults in contact, as the §5 run: every pressing move is bounded by the cell's
press guard (:mod:`forcelearn.press_guard`, along each point's force axis; the
probe's stiffness known once it ran; its state in the checkpoint), each pass's
first contact (and the probe's) is pressed twice with a zero check between
(:meth:`~forcelearn.tasks.path.PathTask.press_again`), and with
``[task] zero_check`` (on by default) every pass and the probe end with a zero check
in free space, after the retreat (:class:`PathRecovery`): a zero that moved voids
the pass (rolled back, re-zeroed, run again; ``voided`` in ``faults.jsonl``).
"""

from __future__ import annotations

import contextlib
import logging
import math
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from forcelearn.cell import Cell
from forcelearn.errors import ConfigError, ForcelearnError, PathRefused
from forcelearn.learning import SRVLearner, load_learner
from forcelearn.paths import TaughtPath
from forcelearn.press_guard import PressGuard
from forcelearn.records import TrialRecords
from forcelearn.site import CellConfig, CellSession
from forcelearn.tasks.path import PathGeometry, PathTask, offset_output
from forcelearn.tasks.path_probe import probe_pass, warm_start
from forcelearn.tasks.path_spec import PathTaskSpec, load_task_path
from forcelearn.tools.experiments.fault_recovery import RunRecovery
from forcelearn.tools.experiments.path_outputs import (
    END_WINDOW,
    add_tangential,
    end_lines,
    write_outputs,
    write_probe,
)
from forcelearn.tools.experiments.path_state import (
    CHECKPOINT,
    PathRun,
    restore,
    save_checkpoint,
)
from forcelearn.tools.experiments.records import (
    PROBE_TRIAL,
    RECORDS_FILE,
    RecordsWriter,
    scan_records,
)
from forcelearn.tools.experiments.run_recorder import TrialRecorder
from forcelearn.trainer import StepHook, TrialLog, TrialRecord, train

__all__ = ["DEFAULT_PASSES", "END_WINDOW", "end_lines", "execute", "load_path", "run_path"]

log = logging.getLogger(__name__)

PassHook = Callable[[TrialRecord, SRVLearner], Any]
"""``on_pass(record, learner)``: after each pass, once it is checkpointed."""
DEFAULT_PASSES = 25
"""Passes of a path run when neither ``--trials`` nor ``[run] trials`` says."""


def load_path(config: CellConfig) -> TaughtPath:
    """The config's path, read, resampled and checked; every point ± max_deviation too."""
    spec = config.path_task
    if spec is None:
        raise ConfigError("this config has no path task: set [task] kind = \"path\" and "
                          "path = FILE, or give forcelearn run --path FILE")
    safety = config.safety
    if config.robot_emulated and config.emulator.part is None:
        raise ConfigError("the path task on the emulated cell needs a part to press: add an "
                          "[emulator.part] table (docs/path.md; examples/paths/*-cell.toml)")
    if spec.desired_force_n + spec.tolerance > safety.max_force_n:
        raise ConfigError(
            f"task.desired_force_n = {spec.desired_force_n:g} N plus its tolerance "
            f"{spec.tolerance:g} N passes safety.max_force_n = {safety.max_force_n:g} N: raise "
            "the limit (FC Pressure's FCSupvForce) or lower the force")
    path = load_task_path(spec, safety.workspace_min_mm, safety.workspace_max_mm,
                          safety.max_step_mm)
    check_deviation(path, spec, safety.workspace_min_mm, safety.workspace_max_mm)
    return path


def check_deviation(path: TaughtPath, spec: PathTaskSpec, low: tuple[float, float, float],
                    high: tuple[float, float, float]) -> None:
    """Refuse a path whose points ± ``max_deviation_mm`` along the force axis leave the box."""
    points = PathGeometry(path, spec.force_axis)
    for k in range(len(points)):
        for sign in (-1.0, 1.0):
            pose = points.pose(k, sign * spec.max_deviation_mm)
            where = np.array([pose.x_mm, pose.y_mm, pose.z_mm])
            if np.any(where < low) or np.any(where > high):
                raise PathRefused(
                    k, path.names[k], path.lines[k],
                    f"{sign * spec.max_deviation_mm:+g} mm along the force axis "
                    f"(task.max_deviation_mm) it would be at "
                    f"({', '.join(f'{v:.6g}' for v in where)}) mm, outside the workspace "
                    "(safety.workspace_min_mm/_max_mm)")


class PathRecovery(RunRecovery):
    """The §5 run's recovery, for a tool that turns.

    Its zero check is the §5 run's (a software zero keeps the calibration of the sensor's
    zero at any orientation: :meth:`~forcelearn.cell.Cell.check_zero`). Every fault counts
    as one of a pass's tries: the path run has no bias watch whose margins a false alarm
    could widen.
    """

    def _recover(self, exc: ForcelearnError, trial: int, attempt: int) -> bool:
        super()._recover(exc, trial, attempt)
        return False


def run_path(config: CellConfig, out: Path, passes: int, seed: int,
             on_pass: PassHook | None = None, figures: bool = True) -> dict[str, Any]:
    """Probe, learn ``passes`` passes, write the run directory; return the summary.

    A run of a config held in memory (the study's): it checkpoints, but its resume needs
    the config file (``forcelearn run --config FILE``).
    """
    return execute(PathRun(config, passes, seed, out), None, on_pass=on_pass, figures=figures)


def execute(run: PathRun, state: dict[str, Any] | None, on_pass: PassHook | None = None,
            on_step: StepHook | None = None, figures: bool = True) -> dict[str, Any]:
    """Open the cell and run (or continue: ``state``, the checkpoint's) the passes.

    Ctrl-C or an error the run does not recover from stops the robot and retracts it
    along the force axis; the passes done are already on disk and the outputs are
    written for them before the exception propagates.
    """
    config, out = run.config, run.out
    spec = config.path_task
    path = load_path(config)
    assert spec is not None
    out.mkdir(parents=True, exist_ok=True)
    started, wall_before = time.perf_counter(), run.wall_s
    with CellSession(config, seed=run.seed) as session, contextlib.ExitStack() as stack:
        cell = session.cell
        assert cell is not None
        cell.press_guard = PressGuard(config.safety.max_force_n, spec.press_stiffness_n_per_mm,
                                      cell.force_filter.measurement_variance_n2 ** 0.5)
        if state is not None:  # the emulators, the cell's software zero and its guard
            session.load_emulator_state(restore(run, state))
            if run.zero_quaternion is not None:  # the restored sensor's zero, not this open's
                cell.zero_taken_at(run.zero_quaternion)
        done = len(run.result.records)
        writer = RecordsWriter(out / RECORDS_FILE, kept_records(out, done, state is not None))
        stack.callback(writer.close)
        recorder = TrialRecorder(cell)
        recovery = PathRecovery(out, cell, math.nan, config.safety.max_step_mm,
                                checkpoint=out / CHECKPOINT, zero_check=spec.zero_check,
                                watch=False)
        task = run.task = PathTask(
            cell, spec, path, config.safety.max_step_mm, stiffness_n_per_mm=1.0,
            verify_contact=True,
            zero_check=lambda: recovery.check_zero(len(run.result.records) if run.probe else -1))
        recovery.away = task.away
        learner = start(run, task, cell, recovery, recorder, writer)

        def after(record: TrialRecord, trial_log: TrialLog, learner: SRVLearner) -> None:
            recovery.check_zero(record.index)  # free space after the retreat: void if it moved
            records = recorder.take(record.index)
            writer.write_trial(records)  # durable before the checkpoint that counts the pass
            add_tangential(trial_log, records, config.filter)
            run.logs.append(trial_log)
            run.wall_s = wall_before + time.perf_counter() - started
            if cell.calibration is not None:
                run.zero_quaternion = cell.calibration.zero_quaternion
            save_checkpoint(run, learner, session.emulator_state())
            if on_pass is not None:
                on_pass(record, learner)

        cell.recorder = recorder
        try:  # a device fault: retract along the force axis, re-zero, the pass again
            learner = recovery.train(learner, run, lambda learner, remaining: train(
                learner, task, remaining, on_trial=after, result=run.result, on_step=on_step))
        except (KeyboardInterrupt, ForcelearnError) as exc:
            cell.stop()
            run.rollback_to_saved()
            recovery.on_exit(exc, len(run.result.records))
            write_outputs(run, path, cell.time_s, figures)
            raise
        finally:
            cell.recorder = None
            recorder.discard()
        cell_time_s = cell.time_s
    run.wall_s = wall_before + time.perf_counter() - started
    return write_outputs(run, path, cell_time_s, figures)


def start(run: PathRun, task: PathTask, cell: Cell, recovery: RunRecovery,
          recorder: TrialRecorder, writer: RecordsWriter) -> SRVLearner:
    """The learner to run the passes with: a new run's after its probe, a resumed run's saved.

    A resumed run whose last session stopped in contact first retracts and re-zeroes.
    """
    spec = task.spec
    done = len(run.result.records)
    if run.probe is not None:  # resumed: the probe, the task and the learner as saved
        task.output = offset_output(run.probe.scale_mm, spec.max_deviation_mm)
        know_stiffness(cell, run.probe.stiffness_n_per_mm)
        assert run.saved.task_state is not None
        task.load_state_dict(run.saved.task_state)
        try:
            recovery.on_resume()
        except (KeyboardInterrupt, ForcelearnError) as exc:
            recovery.on_exit(exc, done)
            raise
        return load_learner(run.out / CHECKPOINT, output=task.output)[0]
    cell.recorder = recorder
    try:
        run.probe = probe = recovery.probe(lambda: probe_pass(task))
    except (KeyboardInterrupt, ForcelearnError) as exc:
        recovery.on_exit(exc, -1)
        raise
    finally:
        cell.recorder = None
    probed = recorder.take(PROBE_TRIAL)
    if probed.steps:
        writer.write_trial(probed)
    write_probe(run.out, probe)
    know_stiffness(cell, probe.stiffness_n_per_mm)
    task.output = offset_output(probe.scale_mm, spec.max_deviation_mm)
    learner = SRVLearner(task.grid, 1, run.config.learner, rng=run.seed, output=task.output)
    warm_start(learner, probe)
    run.start_task_state = task.state_dict()
    return learner


def know_stiffness(cell: Cell, stiffness_n_per_mm: float) -> None:
    """The press guard knows the part's stiffness along the force axis (the probe's), N/mm."""
    if cell.press_guard is not None and stiffness_n_per_mm > 0:
        cell.press_guard.know(stiffness_n_per_mm)


def kept_records(out: Path, done: int, resumed: bool) -> list[TrialRecords]:
    """A resumed run's records.mcap rewound to its checkpoint: the probe and whole passes."""
    path = out / RECORDS_FILE
    if not (resumed and path.exists()):
        return []
    return [t for t in scan_records(path).trials if t.trial < done]


