"""Paper §5 on a cell: the trial loop with a checkpoint after every trial, and resume.

The run directory holds:

=====================  ==========================================================
``checkpoint.npz``     the learner plus, in its metadata, everything else a resume
                       needs: trial records, kept step logs, per-trial Y traces,
                       the emulators' state (sponge wear, sensor noise generator,
                       bias, offsets). One file, written atomically after every
                       trial, so a run killed at any instant resumes from a whole
                       trial.
``config.toml``        the cell config the run started with (resume reads it)
``records.mcap``       every move, burst and tare of every trial (docs/records.md),
                       made durable per trial before the checkpoint
``summary.json``       task, seed, learner_start, trials, phase_switch_trial,
                       criterion_trial, converged_trial, converged,
                       in_band_at_end, trials_out_of_band_after_convergence,
                       diagnosis, feasibility, final_force_rms_n, final_mean_r,
                       map_shift_mm, steps, wall_s, steps_per_s, output_map,
                       probe (fits), ...
``probe.csv``          the surface probe's readings (``probe.png`` its figure)
``trials.csv``         one row per trial
``steps_*.csv``        step logs: first trial, mid-way, phase switch, last trial
``fig12..14*.png``     the paper's Figs. 12-14
=====================  ==========================================================

A new run first probes the surface (:mod:`forcelearn.tasks.surface_probe`)
and takes its output map from the fit; the probe and the map are kept in the
checkpoint, so a resumed run does not probe again. The learner starts from the
probe's path (``[run] learner_start = "probe"``) or from μ = 0 (``"cold"``,
:mod:`forcelearn.tasks.surface_warm_start`). During the run a
:class:`~forcelearn.tasks.surface_diagnosis.StuckMonitor` warns (once, through
``on_warning`` and the log) when learning is stuck, and
:func:`~forcelearn.tasks.surface_feasibility.assess` when the run's own
estimates say the desired force is out of reach after wear.

A resumed run re-opens the cell, restores the learner (with its random
generator) and, on an emulated cell, the emulators' state, then continues with
the next trial: it ends bit-identical to an uninterrupted run with the same seed.
"""

from __future__ import annotations

import contextlib
import dataclasses
import logging
import shutil
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from forcelearn.errors import ForcelearnError, StateFileError
from forcelearn.learning import SRVLearner, load_extra_arrays, load_learner, save_learner
from forcelearn.records import TrialRecords
from forcelearn.run_output import final_figures, write_step_log, write_summary, write_trials
from forcelearn.site.config import CellConfig, load_cell_config
from forcelearn.site.session import CellSession
from forcelearn.tasks.surface import SurfaceTask, TrialTrace
from forcelearn.tasks.surface_diagnosis import StuckMonitor, diagnose
from forcelearn.tasks.surface_feasibility import FEASIBILITY_WINDOW, Feasibility, assess
from forcelearn.tasks.surface_map import (
    OutputMapChoice,
    SurfaceYOutput,
    allowed_bottom_y_mm,
    step_centre_y_mm,
)
from forcelearn.tasks.surface_probe import ProbeResult, SurfaceProbe, probe_and_map
from forcelearn.tasks.surface_warm_start import OLD_CHECKPOINT_START, warm_start
from forcelearn.tools.experiments.records import (
    PROBE_TRIAL,
    RECORDS_FILE,
    RecordsWriter,
    scan_records,
)
from forcelearn.tools.experiments.run_recorder import TrialRecorder
from forcelearn.trainer import (
    CONVERGENCE_TOLERANCE,
    StepHook,
    TrainingResult,
    TrialLog,
    TrialRecord,
    converged_trial,
    criterion_trial,
    train,
)

log = logging.getLogger(__name__)


class _ConvergedStop(Exception):
    """Raised after a trial to end a run early (``[run] stop_after_converged``)."""

CHECKPOINT = "checkpoint.npz"
CONFIG_COPY = "config.toml"
RUN_STATE_VERSION = 5
"""4: the probe's result and the output map in the metadata (issue 11); 5: the learner's
start, the wear tracking's reference force and the feasibility (issue 31). A version-4
checkpoint still resumes: cold start, and the wear tracking it ran with."""
READABLE_VERSIONS = (4, 5)


@dataclasses.dataclass(frozen=True)
class SavedPoint:
    """What the checkpoint on disk holds of a run's growing state, to roll back to."""

    trials: int = 0
    """Whole trials saved."""
    steps: int = 0
    """Steps of those trials."""
    last_log: TrialLog | None = None
    """The last saved trial's step log."""
    map_shift_mm: float = 0.0
    """The map's wear shift, mm."""
    map_recentre_mm: float = 0.0
    """The map's re-centring on the learner, mm."""
    tares: tuple[int, int] = (0, 0)
    """Tares done and refused."""
    wear_reference_n: float | None = None
    """The wear tracking's reference start force, N."""


@dataclasses.dataclass
class SurfaceRun:
    """Where a run stands: its config, target trial count, results so far and traces."""

    config: CellConfig
    trials: int
    seed: int
    out: Path
    result: TrainingResult = dataclasses.field(default_factory=TrainingResult)
    traces: list[TrialTrace] = dataclasses.field(default_factory=list)
    """Per trial: the Y commands and the map's wear shift."""
    wall_s: float = 0.0
    saved: SavedPoint = dataclasses.field(default_factory=SavedPoint)
    """What the last checkpoint holds of the growing state (a rollback returns there)."""
    probe: ProbeResult | None = None
    """The surface probe's readings and fits (None: no probe)."""
    output_map: OutputMapChoice | None = None
    """The output map the learner uses (from the probe and/or the config)."""
    monitor: StuckMonitor | None = None
    """Watches for stuck learning (edge of the range, no trial completing)."""
    map_shift_mm: float = 0.0
    """A map that follows wear: its shift as of the last whole trial (mm)."""
    map_recentre_mm: float = 0.0
    """A map that follows wear: its re-centring on the learner's drift, as of the last whole
    trial (mm; :meth:`~forcelearn.tasks.surface.SurfaceYOutput.recentre_on`)."""
    tares: tuple[int, int] = (0, 0)
    """``task.tare_each_trial``: tares done and refused, as of the last whole trial."""
    learner_start: str = OLD_CHECKPOINT_START
    """How the learner started: "probe" (warm) or "cold" (set by :func:`execute`)."""
    wear_reference_n: float | None = None
    """The start force the wear tracking holds (the first trial's), N."""
    feasibility: Feasibility | None = None
    """The latest 'out of reach' estimate the run made (None: never)."""
    feasibility_now: bool = False
    """True when the latest trial's window still says the force is out of reach."""
    feasibility_first_trial: int | None = None
    """The trial at which the run first found the force out of reach."""

    def mark_saved(self) -> None:
        """Remember what the checkpoint on disk holds."""
        result = self.result
        self.saved = SavedPoint(
            len(result.records), result.steps, result.last_log, self.map_shift_mm,
            self.map_recentre_mm, self.tares, self.wear_reference_n,
        )

    def rollback_to_saved(self) -> None:
        """Forget a trial that ended but was not checkpointed (interrupted in between)."""
        saved, result = self.saved, self.result
        trials = saved.trials
        self.map_shift_mm, self.map_recentre_mm = saved.map_shift_mm, saved.map_recentre_mm
        self.tares, self.wear_reference_n = saved.tares, saved.wear_reference_n
        del result.records[trials:]
        del self.traces[trials:]
        result.steps, result.last_log = saved.steps, saved.last_log
        result.logs = {k: v for k, v in result.logs.items() if k < trials}
        if result.switch_trial is not None and result.switch_trial >= trials:
            result.switch_trial, result.switch_log = None, None
        if trials == 0:
            result.first_log = None

    @property
    def mid_trial(self) -> int:
        """The trial whose step log stands for 'mid-way' in Fig. 13."""
        return self.trials // 2


def _log_to_json(trial_log: TrialLog | None) -> dict[str, Any] | None:
    if trial_log is None:
        return None
    return {"index": trial_log.index, "phase": trial_log.phase, "rows": trial_log.rows}


def _log_from_json(data: dict[str, Any] | None) -> TrialLog | None:
    if data is None:
        return None
    return TrialLog(int(data["index"]), str(data["phase"]), list(data["rows"]))


_RECORD_FIELDS = [f.name for f in dataclasses.fields(TrialRecord)]


def _history_arrays(run: SurfaceRun) -> dict[str, np.ndarray]:
    """The growing history as arrays (cheap to save every trial, exact on reload)."""
    records = run.result.records
    arrays = {
        f"record_{name}": np.array([getattr(r, name) for r in records]) for name in _RECORD_FIELDS
    }
    steps = run.config.task.steps_per_trial
    means = np.full((len(run.traces), steps), np.nan)
    commands = np.full((len(run.traces), steps), np.nan)
    forces = np.full((len(run.traces), steps), np.nan)
    for i, trace in enumerate(run.traces):
        means[i, : len(trace["mean_y_mm"])] = trace["mean_y_mm"]
        commands[i, : len(trace["command_y_mm"])] = trace["command_y_mm"]
        forces[i, : len(trace["force_n"])] = trace["force_n"]
    arrays["trace_mean_y_mm"], arrays["trace_command_y_mm"] = means, commands
    arrays["trace_force_n"] = forces
    arrays["trace_length"] = np.array([len(t["mean_y_mm"]) for t in run.traces], dtype=np.int64)
    arrays["trace_shift_mm"] = np.array([t["shift_mm"] for t in run.traces], dtype=float)
    return arrays


def _history_from_arrays(run: SurfaceRun, arrays: dict[str, np.ndarray]) -> None:
    count = len(arrays["record_index"])
    run.result.records = [
        TrialRecord(**{name: arrays[f"record_{name}"][i].item() for name in _RECORD_FIELDS})
        for i in range(count)
    ]
    lengths = arrays["trace_length"].tolist()
    # checkpoints written before the shift was kept per trial: no shift known (0)
    shifts = arrays.get("trace_shift_mm", np.zeros(len(lengths))).tolist()
    if len(shifts) != len(lengths):
        raise StateFileError(
            f"{run.out / CHECKPOINT} keeps {len(shifts)} trial shifts for {len(lengths)} "
            "trials (a damaged file); restore it from a backup or start a new run"
        )
    # checkpoints written before the forces were kept per step: none known (NaN)
    forces = arrays.get("trace_force_n", np.full(arrays["trace_command_y_mm"].shape, np.nan))
    run.traces = [
        TrialTrace(
            mean_y_mm=arrays["trace_mean_y_mm"][i, :length].tolist(),
            command_y_mm=arrays["trace_command_y_mm"][i, :length].tolist(),
            shift_mm=float(shifts[i]),
            force_n=forces[i, :length].tolist(),
        )
        for i, length in enumerate(lengths)
    ]


def _run_state(run: SurfaceRun, emulator_state: dict[str, Any]) -> dict[str, Any]:
    result = run.result
    return {
        "run_state_version": RUN_STATE_VERSION,
        "task": "surface",
        "seed": run.seed,
        "trials_target": run.trials,
        "trials_done": len(result.records),
        "switch_trial": result.switch_trial,
        "switch_log": _log_to_json(result.switch_log),
        "first_log": _log_to_json(result.first_log),
        "last_log": _log_to_json(result.last_log),
        "logs": {str(k): _log_to_json(v) for k, v in result.logs.items()},
        "steps": result.steps,
        "wall_s": run.wall_s,
        "emulator": emulator_state,
        "probe": run.probe.to_json() if run.probe is not None else None,
        "output_map": dataclasses.asdict(run.output_map) if run.output_map else None,
        "map_shift_mm": run.map_shift_mm,
        "map_recentre_mm": run.map_recentre_mm,
        "tares": list(run.tares),
        "learner_start": run.learner_start,
        "wear_reference_n": run.wear_reference_n,
        "feasibility": (
            dataclasses.asdict(run.feasibility) if run.feasibility is not None else None
        ),
        "feasibility_now": run.feasibility_now,
        "feasibility_first_trial": run.feasibility_first_trial,
    }


def _restore(run: SurfaceRun, state: dict[str, Any], arrays: dict[str, np.ndarray]) -> None:
    version = state.get("run_state_version")
    if version not in READABLE_VERSIONS or state.get("task") != "surface":
        raise StateFileError(
            f"{run.out / CHECKPOINT} is not a surface-run checkpoint of version "
            f"{' or '.join(map(str, READABLE_VERSIONS))}; start a new run in another folder"
        )
    result = run.result
    _history_from_arrays(run, arrays)
    result.switch_trial = state["switch_trial"]
    result.switch_log = _log_from_json(state["switch_log"])
    result.first_log = _log_from_json(state["first_log"])
    result.last_log = _log_from_json(state["last_log"])
    result.logs = {int(k): _log_from_json(v) for k, v in state["logs"].items()}  # type: ignore[misc]
    result.steps = int(state["steps"])
    run.wall_s = float(state["wall_s"])
    run.probe = ProbeResult.from_json(state["probe"]) if state["probe"] is not None else None
    run.output_map = OutputMapChoice(**state["output_map"])
    run.map_shift_mm = float(state.get("map_shift_mm", 0.0))
    run.map_recentre_mm = float(state.get("map_recentre_mm", 0.0))  # none before it existed
    # before version 5: the cold start, and a map that tracked wear held the desired force
    run.learner_start = str(state.get("learner_start", OLD_CHECKPOINT_START))
    if "wear_reference_n" in state:
        reference = state["wear_reference_n"]
        run.wear_reference_n = None if reference is None else float(reference)
    elif run.output_map.wear_stiffness_n_per_mm is not None:
        run.wear_reference_n = float(run.config.task.desired_force_n)
    feasibility = state.get("feasibility")
    run.feasibility = Feasibility(**feasibility) if feasibility else None
    run.feasibility_now = bool(state.get("feasibility_now", False))
    first = state.get("feasibility_first_trial")
    run.feasibility_first_trial = None if first is None else int(first)
    try:
        done, refused = state.get("tares", (0, 0))  # none in older checkpoints
        run.tares = (int(done), int(refused))
    except (TypeError, ValueError) as exc:
        raise StateFileError(
            f"{run.out / CHECKPOINT} has a damaged tare count {state.get('tares')!r}; "
            "restore it from a backup or start a new run"
        ) from exc


def prepare_run(
    config_path: Path | None, out: Path, trials: int | None, seed: int | None, resume: bool
) -> tuple[SurfaceRun, Path | None]:
    """Set up a new run directory, or read the one to resume; returns the run and checkpoint."""
    if resume:
        if not (out / CHECKPOINT).exists():
            raise StateFileError(
                f"nothing to resume in {out}: no {CHECKPOINT} (runs write it after their first "
                "trial); start a new run with --out"
            )
        copy = out / CONFIG_COPY
        config = load_cell_config(copy if copy.exists() else None)
        _, metadata = load_learner(out / CHECKPOINT)
        run = SurfaceRun(
            config, trials or int(metadata["trials_target"]), int(metadata["seed"]), out
        )
        return run, out / CHECKPOINT
    if (out / CHECKPOINT).exists():
        raise StateFileError(
            f"{out} already holds a run; resume it with --resume {out} or choose another --out"
        )
    config = load_cell_config(config_path)
    out.mkdir(parents=True, exist_ok=True)
    if config_path is not None:
        shutil.copyfile(config_path, out / CONFIG_COPY)
    run = SurfaceRun(
        config,
        trials if trials is not None else config.trials,
        seed if seed is not None else config.seed,
        out,
    )
    return run, None


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

    Ctrl-C (KeyboardInterrupt) or any device error stops the robot; the last
    whole trial is already on disk, and the outputs are written for the trials
    done before the exception propagates.
    """
    config = run.config
    started = time.perf_counter()
    wall_before = run.wall_s
    with CellSession(config, seed=run.seed) as session, contextlib.ExitStack() as stack:
        assert session.cell is not None
        if checkpoint is not None:
            state = load_learner(checkpoint)[1]
            _restore(run, state, load_extra_arrays(checkpoint))
            session.load_emulator_state(state["emulator"])
            run.mark_saved()
        writer = records_writer(run, checkpoint is not None)
        stack.callback(writer.close)
        recorder = TrialRecorder(session.cell)
        if checkpoint is None:
            session.cell.recorder = recorder
            try:
                probe_and_choose(run, session)
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
        )
        remaining = run.trials - len(run.result.records)
        try:
            if remaining > 0:
                train(
                    learner,
                    task,
                    remaining,
                    keep_logs=(run.mid_trial,),
                    on_trial=trial_end,
                    result=run.result,
                    on_step=on_step,
                )
        except _ConvergedStop:
            log.info("converged; stopped %d trials later", config.stop_after_converged)
        except (KeyboardInterrupt, ForcelearnError):
            session.cell.stop()
            run.rollback_to_saved()
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

    def __call__(self, record: TrialRecord, trial_log: TrialLog, learner: SRVLearner) -> None:
        """Book the trial that just ended (raises ``_ConvergedStop`` to end the run)."""
        run = self.run
        run.traces.append(self._trace(trial_log))
        run.wall_s = self._wall_before + time.perf_counter() - self._started
        self._follow_map(learner)
        new_finding = self._assess(record.index)
        cell, before = self.cell, self._tares_before
        run.tares = (before[0] + cell.tares, before[1] + cell.tares_refused)
        self.writer.write_trial(self.recorder.take(record.index))
        save_learner(
            learner,
            run.out / CHECKPOINT,
            metadata=_run_state(run, self.session.emulator_state()),
            arrays=_history_arrays(run),
        )
        run.mark_saved()
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


def probe_and_choose(run: SurfaceRun, session: CellSession) -> None:
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


def write_probe_files(
    out: Path, probe: ProbeResult, choice: OutputMapChoice | None
) -> None:
    """probe.csv (every reading), probe.json (fits and map) and probe.png (the figure)."""
    import csv
    import json

    from forcelearn.tools.figures import probe as figures_probe

    out.mkdir(parents=True, exist_ok=True)
    with open(out / "probe.csv", "w", newline="") as handle:
        fields = ["point", "z_mm", "y_mm", "phase", "early_force_n", "force_n", "cell_time_s"]
        writer = csv.DictWriter(handle, fieldnames=fields)
        writer.writeheader()
        writer.writerows(probe.rows)
    data = {**probe.to_json(), "output_map": dataclasses.asdict(choice) if choice else None}
    del data["rows"]
    (out / "probe.json").write_text(json.dumps(data, indent=2))
    if probe.rows:
        figures_probe.write_probe_figure(probe, choice, out / "probe.png")


def summary_of(run: SurfaceRun, learner: SRVLearner) -> dict[str, Any]:
    """The run's summary.json content."""
    result, config = run.result, run.config
    cell_time = float(sum(r.cell_time_s for r in result.records))
    converged_at = converged_trial(
        result.records, config.task.steps_per_trial, config.task.desired_force_n
    )
    monitor = run.monitor or StuckMonitor(0.0, 1.0, config.task.steps_per_trial)
    verdict = diagnose(
        result.records, converged_at, monitor, config.task.desired_force_n, run.feasibility
    )
    warnings = list(monitor.warnings)
    if run.feasibility is not None:
        warnings.append(run.feasibility.text())
    return {
        "task": "surface",
        "seed": run.seed,
        "learner_start": run.learner_start,
        "trials": len(result.records),
        "phase_switch_trial": result.switch_trial,
        "criterion_trial": criterion_trial(result.records, config.learner.success_trials),
        "converged_trial": converged_at,
        **verdict,
        "feasibility": {
            "out_of_reach_at_end": run.feasibility_now,
            "first_trial": run.feasibility_first_trial,
            "latest": dataclasses.asdict(run.feasibility) if run.feasibility else None,
        },
        "warnings": warnings,
        "output_map": dataclasses.asdict(run.output_map) if run.output_map else None,
        "map_shift_mm": run.map_shift_mm,
        "map_recentre_mm": run.map_recentre_mm,
        "wear_reference_n": run.wear_reference_n,
        "tares": {"done": run.tares[0], "refused": run.tares[1]},
        "probe_stiffness_n_per_mm": (
            run.probe.stiffness_n_per_mm() if run.probe is not None else None
        ),
        "probe_fits": (
            [dataclasses.asdict(f) for f in run.probe.fits] if run.probe is not None else None
        ),
        **final_figures(result.records),
        "failures": sum(r.failed for r in result.records),
        "desired_force_n": config.task.desired_force_n,
        "emulated": config.robot_emulated and config.sensor_emulated,
        "steps": result.steps,
        "wall_s": round(run.wall_s, 3),
        "steps_per_s": round(result.steps / run.wall_s, 1) if run.wall_s > 0 else None,
        "cell_time_s": round(cell_time, 3),
        "realtime_factor": round(cell_time / run.wall_s, 1) if run.wall_s > 0 else None,
        "profile": config.emulator.profile if config.robot_emulated else None,
    }


def write_outputs(run: SurfaceRun, learner: SRVLearner) -> dict[str, Any]:
    """Write summary.json, trials.csv, the step logs and the figures; return the summary."""
    from forcelearn.tools.figures import surface as figures_surface

    summary = summary_of(run, learner)
    write_summary(run.out, summary)
    write_trials(run.out, run.result.records)
    result = run.result
    named = {
        "first": result.first_log,
        "switch": result.switch_log,
        "final": result.last_log,
        "mid": result.logs.get(run.mid_trial),
    }
    for name, trial_log in named.items():
        if trial_log is not None:
            write_step_log(run.out / f"steps_{name}.csv", trial_log)
    if result.records:
        figures_surface.write_all(run, run.out)
    return summary
