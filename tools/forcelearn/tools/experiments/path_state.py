"""The path run's state: what its ``checkpoint.npz`` holds, and how a run is set up or resumed.

One file, written atomically after every pass (:func:`save_checkpoint`, through
:func:`forcelearn.learning.save_learner`, as the §5 run's), holds the learner
(with its random generator) and, in its metadata: the run's source (the config
file, its digest, the ``--path`` given), seed and pass target, the probe pass,
the task's state after the pass (:meth:`~forcelearn.tasks.path.PathTask.state_dict`:
counters, contact, the wear shift), every pass's record and step log, and the
emulators' state. A resumed run re-opens the cell, restores all of it and goes
on with the next pass: it ends with the trials, passes and steps of an
uninterrupted run with the same seed.

=====================  =========================================================
``task``               ``"path"``; ``path_state_version``: :data:`PATH_STATE_VERSION`
``config``             the config file (absolute) and its SHA-256; a resume
                       refuses a config that changed since
``task_path``          ``forcelearn run --path FILE`` (absolute), or None
``seed``, ``passes``   the run's seed and pass target
``probe``              :class:`~forcelearn.tasks.path_probe.PathProbe`'s fields
``task_state``         the task after the last whole pass
``records``, ``logs``  each pass's trials.csv row and step log
``emulator``           the emulated cell's state (empty on a real cell)
=====================  =========================================================
"""

from __future__ import annotations

import dataclasses
import hashlib
import shutil
from pathlib import Path
from typing import Any

from forcelearn.errors import StateFileError
from forcelearn.learning import SRVLearner, load_learner, save_learner
from forcelearn.site import CellConfig, load_cell_config
from forcelearn.tasks.path import PathTask
from forcelearn.tasks.path_probe import PathProbe
from forcelearn.trainer import TrainingResult, TrialLog, TrialRecord

CHECKPOINT = "checkpoint.npz"
CONFIG_COPY = "config.toml"
PATH_STATE_VERSION = 1
"""The path run's checkpoint format (``path_state_version`` in the metadata)."""


@dataclasses.dataclass(frozen=True)
class SavedPoint:
    """What the checkpoint on disk holds of a run's growing state (a rollback returns there)."""

    trials: int = 0
    """Whole passes saved."""
    steps: int = 0
    task_state: dict[str, Any] | None = None
    """The task after the last saved pass (None: as the probe left it)."""


@dataclasses.dataclass
class PathRun:
    """Where a path run stands: its config and source, target, passes so far, the probe."""

    config: CellConfig
    trials: int
    """Passes of the run (the trainer's trials)."""
    seed: int
    out: Path
    config_path: Path | None = None
    task_path: Path | None = None
    result: TrainingResult = dataclasses.field(default_factory=TrainingResult)
    logs: list[TrialLog] = dataclasses.field(default_factory=list)
    """Every pass's step log (passes.csv, steps.csv, the figures)."""
    probe: PathProbe | None = None
    wall_s: float = 0.0
    task: PathTask | None = None
    """The live task (set by the run engine): a rollback restores its state too."""
    saved: SavedPoint = dataclasses.field(default_factory=SavedPoint)
    start_task_state: dict[str, Any] | None = None
    """The task as the probe left it (what a rollback before the first pass returns to)."""
    zero_quaternion: tuple[float, float, float, float] | None = None
    """The orientation of the sensor's last zero (the calibration's): the emulated sensor's
    state a resume restores holds that zero."""

    def mark_saved(self) -> None:
        """Remember what the checkpoint on disk holds."""
        state = self.task.state_dict() if self.task is not None else None
        self.saved = SavedPoint(len(self.result.records), self.result.steps, state)

    def rollback_to_saved(self) -> None:
        """Forget a pass that did not end or was not checkpointed; the task as saved."""
        trials, result = self.saved.trials, self.result
        del result.records[trials:]
        del self.logs[trials:]
        result.steps = self.saved.steps
        result.last_log = self.logs[-1] if self.logs else None
        result.logs = {k: v for k, v in result.logs.items() if k < trials}
        if result.switch_trial is not None and result.switch_trial >= trials:
            result.switch_trial, result.switch_log = None, None
        if trials == 0:
            result.first_log = None
        state = self.saved.task_state if trials else self.start_task_state
        if self.task is not None and state is not None:
            self.task.load_state_dict(state)


def digest(path: Path) -> str:
    """SHA-256 of a file's bytes (the config a run began with)."""
    return hashlib.sha256(path.read_bytes()).hexdigest()


def _log_json(trial_log: TrialLog) -> dict[str, Any]:
    return {"index": trial_log.index, "phase": trial_log.phase, "rows": trial_log.rows}


def state_of(run: PathRun, emulator_state: dict[str, Any]) -> dict[str, Any]:
    """The checkpoint's metadata (JSON-safe; floats round-trip exactly)."""
    assert run.task is not None and run.probe is not None
    result = run.result
    return {
        "path_state_version": PATH_STATE_VERSION, "task": "path",
        "config": None if run.config_path is None else str(run.config_path.resolve()),
        "config_sha256": None if run.config_path is None else digest(run.config_path),
        "task_path": None if run.task_path is None else str(run.task_path.resolve()),
        "seed": run.seed, "passes": run.trials, "wall_s": run.wall_s,
        "probe": dataclasses.asdict(run.probe),
        "task_state": run.task.state_dict(),
        "start_task_state": run.start_task_state,
        "records": [dataclasses.asdict(r) for r in result.records],
        "logs": [_log_json(trial_log) for trial_log in run.logs],
        "switch_trial": result.switch_trial, "steps": result.steps,
        "emulator": emulator_state,
        "zero_quaternion": list(run.zero_quaternion) if run.zero_quaternion else None,
    }


def save_checkpoint(run: PathRun, learner: SRVLearner, emulator_state: dict[str, Any]) -> None:
    """Write the run's checkpoint atomically and remember what it holds."""
    save_learner(learner, run.out / CHECKPOINT, metadata=state_of(run, emulator_state))
    run.mark_saved()


def restore(run: PathRun, state: dict[str, Any]) -> dict[str, Any]:
    """Set the run from a checkpoint's metadata; return the emulators' state.

    The task's own state is applied by the engine (:meth:`PathTask.load_state_dict`) once
    the task exists: it is kept in ``run.saved``.
    """
    try:
        probe = state["probe"]
        floats = {key: tuple(float(v) for v in probe[key])
                  for key in ("offsets_mm", "forces_n", "targets_mm", "r_hats")}
        run.probe = PathProbe(
            stiffness_n_per_mm=float(probe["stiffness_n_per_mm"]),
            contact_offset_mm=float(probe["contact_offset_mm"]),
            offsets_mm=floats["offsets_mm"], forces_n=floats["forces_n"],
            targets_mm=floats["targets_mm"], r_hats=floats["r_hats"],
            lost=tuple(int(v) for v in probe["lost"]), tolerance_n=float(probe["tolerance_n"]),
            pass_stiffness_n_per_mm=probe.get("pass_stiffness_n_per_mm"))
        result = run.result
        result.records = [TrialRecord(**r) for r in state["records"]]
        run.logs = [TrialLog(int(d["index"]), str(d["phase"]), list(d["rows"]))
                    for d in state["logs"]]
        result.steps = int(state["steps"])
        result.switch_trial = state["switch_trial"]
        result.switch_log = (run.logs[result.switch_trial]
                             if result.switch_trial is not None else None)
        result.first_log = run.logs[0] if run.logs else None
        result.last_log = run.logs[-1] if run.logs else None
        run.wall_s = float(state["wall_s"])
        run.start_task_state = state["start_task_state"]
        zero = state["zero_quaternion"]
        run.zero_quaternion = None if zero is None else (
            float(zero[0]), float(zero[1]), float(zero[2]), float(zero[3]))
        run.saved = SavedPoint(len(result.records), result.steps, dict(state["task_state"]))
        emulator: dict[str, Any] = state["emulator"]
    except (KeyError, TypeError, ValueError, IndexError) as exc:
        raise StateFileError(f"{run.out / CHECKPOINT} is damaged ({type(exc).__name__}: {exc}); "
                             "restore it from a backup or start a new run") from exc
    return emulator


def prepare_path_run(config_path: Path | None, task_path: Path | None, out: Path,
                     passes: int | None, seed: int | None, default_passes: int,
                     resume: bool) -> tuple[PathRun, dict[str, Any] | None]:
    """A new run directory, or the run in ``out`` to resume; (run, checkpoint metadata or None).

    Raises:
        StateFileError: nothing to resume, a run already in ``out``, another kind of
            checkpoint, or a config that changed since the run began.
    """
    checkpoint = out / CHECKPOINT
    if not resume:
        if checkpoint.exists():
            raise StateFileError(f"{out} already holds a run; resume it with --resume {out} or "
                                 "choose another --out")
        config = load_cell_config(config_path, task_path=task_path)
        out.mkdir(parents=True, exist_ok=True)
        if config_path is not None:
            shutil.copyfile(config_path, out / CONFIG_COPY)
        return PathRun(config, passes or default_passes,
                       config.seed if seed is None else seed, out, config_path, task_path), None
    if not checkpoint.exists():
        raise StateFileError(f"nothing to resume in {out}: no {CHECKPOINT} (runs write it after "
                             "their first pass); start a new run with --out")
    state = load_learner(checkpoint)[1]
    if state.get("task") != "path" or state.get("path_state_version") != PATH_STATE_VERSION:
        raise StateFileError(f"{checkpoint} is not a path run's checkpoint of version "
                             f"{PATH_STATE_VERSION}; start a new run in another folder")
    source = None if state["config"] is None else Path(state["config"])
    if source is not None and (not source.is_file() or digest(source) != state["config_sha256"]):
        raise StateFileError(f"the run's config {source} is missing or changed since the run "
                             f"began (its copy is {out / CONFIG_COPY}): put it back as it was, "
                             "or start a new run")
    given = None if state["task_path"] is None else Path(state["task_path"])
    config = load_cell_config(source, task_path=given)
    run = PathRun(config, passes or int(state["passes"]), int(state["seed"]), out, source, given)
    return run, state
