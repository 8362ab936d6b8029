"""The surface run's state: what ``checkpoint.npz`` holds, and the run directory it lives in.

One file, written atomically after every trial (:func:`save_checkpoint`), holds
the learner (:func:`forcelearn.learning.save_learner`) and, beside it, everything
else a resume needs: in the metadata (``metadata_json``) the run's counters, step
logs, probe, output map, wear tracking, feasibility and the emulators' state; as
``extra_*`` arrays the trial records and per-trial traces. docs/run-directory.md
lists every member with its type and unit, and which format version has it.

:data:`RUN_STATE_VERSION` is the version written; :func:`restore` reads every
version in :data:`READABLE_VERSIONS`, filling what an older file lacks with the
values that version ran with (:func:`upgraded`), so an old run resumes as it ran.
"""

from __future__ import annotations

import dataclasses
import shutil
import tomllib
from pathlib import Path
from typing import Any

import numpy as np

from forcelearn.errors import StateFileError
from forcelearn.learning import SRVLearner, load_extra_arrays, load_learner, save_learner
from forcelearn.site.config import CellConfig, load_cell_config
from forcelearn.tasks.surface import TrialTrace
from forcelearn.tasks.surface_diagnosis import StuckMonitor
from forcelearn.tasks.surface_feasibility import Feasibility
from forcelearn.tasks.surface_map import OutputMapChoice
from forcelearn.tasks.surface_probe import ProbeResult
from forcelearn.tasks.surface_warm_start import OLD_CHECKPOINT_START
from forcelearn.trainer import TrainingResult, TrialLog, TrialRecord

CHECKPOINT = "checkpoint.npz"
CONFIG_COPY = "config.toml"
RUN_STATE_VERSION = 5
"""The checkpoint format written (``run_state_version`` in the metadata); docs/run-directory.md."""
READABLE_VERSIONS = (4, 5)
"""Versions :func:`restore` reads. Version 4 lacks the learner's start, the wear tracking's
reference force and the feasibility: it resumes with the cold start and the wear tracking
it ran with (:func:`upgraded`)."""


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


def history_arrays(run: SurfaceRun) -> dict[str, np.ndarray]:
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


def history_from_arrays(run: SurfaceRun, arrays: dict[str, np.ndarray]) -> None:
    """Set the run's trial records and traces from :func:`history_arrays` (any version)."""
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


def state_of(run: SurfaceRun, emulator_state: dict[str, Any]) -> dict[str, Any]:
    """The checkpoint's metadata of version :data:`RUN_STATE_VERSION` (JSON-safe)."""
    result = run.result
    return {
        "run_state_version": RUN_STATE_VERSION,
        "task": "surface",
        "zero_check": run.config.task.zero_check,
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


def upgraded(state: dict[str, Any], desired_force_n: float) -> dict[str, Any]:
    """An older checkpoint's metadata with every later member set as that version ran.

    Version 4 files (and early ones of version 5) lack members added since; each
    gets the value the run had before it existed: no re-centring and no tares
    counted; the cold start; a map that tracked wear held the desired force
    (``desired_force_n``, N) as its reference; no feasibility estimate.
    """
    done = dict(state)
    done.setdefault("map_shift_mm", 0.0)
    done.setdefault("map_recentre_mm", 0.0)
    done.setdefault("tares", (0, 0))
    done.setdefault("learner_start", OLD_CHECKPOINT_START)
    if "wear_reference_n" not in done:
        output_map = done.get("output_map") or {}
        tracked = output_map.get("wear_stiffness_n_per_mm") is not None
        done["wear_reference_n"] = float(desired_force_n) if tracked else None
    done.setdefault("feasibility", None)
    done.setdefault("feasibility_now", False)
    done.setdefault("feasibility_first_trial", None)
    return done


def restore(run: SurfaceRun, state: dict[str, Any], arrays: dict[str, np.ndarray]) -> None:
    """Set a run from its checkpoint's metadata and arrays (any readable version).

    Raises:
        StateFileError: not a surface run's checkpoint of a readable version, or damaged.
    """
    version = state.get("run_state_version")
    if version not in READABLE_VERSIONS or state.get("task") != "surface":
        raise StateFileError(
            f"{run.out / CHECKPOINT} is not a surface-run checkpoint of version "
            f"{' or '.join(map(str, READABLE_VERSIONS))}; start a new run in another folder"
        )
    state = upgraded(state, run.config.task.desired_force_n)
    result = run.result
    history_from_arrays(run, arrays)
    result.switch_trial = state["switch_trial"]
    result.switch_log = _log_from_json(state["switch_log"])
    result.first_log = _log_from_json(state["first_log"])
    result.last_log = _log_from_json(state["last_log"])
    result.logs = {int(k): _log_from_json(v) for k, v in state["logs"].items()}  # type: ignore[misc]
    result.steps = int(state["steps"])
    run.wall_s = float(state["wall_s"])
    run.probe = ProbeResult.from_json(state["probe"]) if state["probe"] is not None else None
    run.output_map = OutputMapChoice(**state["output_map"])
    run.map_shift_mm = float(state["map_shift_mm"])
    run.map_recentre_mm = float(state["map_recentre_mm"])
    run.learner_start = str(state["learner_start"])
    reference = state["wear_reference_n"]
    run.wear_reference_n = None if reference is None else float(reference)
    feasibility = state["feasibility"]
    run.feasibility = Feasibility(**feasibility) if feasibility else None
    run.feasibility_now = bool(state["feasibility_now"])
    first = state["feasibility_first_trial"]
    run.feasibility_first_trial = None if first is None else int(first)
    try:
        done, refused = state["tares"]
        run.tares = (int(done), int(refused))
    except (TypeError, ValueError) as exc:
        raise StateFileError(
            f"{run.out / CHECKPOINT} has a damaged tare count {state['tares']!r}; "
            "restore it from a backup or start a new run"
        ) from exc


def save_checkpoint(run: SurfaceRun, learner: SRVLearner, emulator_state: dict[str, Any]) -> None:
    """Write the run's checkpoint atomically and remember what it holds (:meth:`mark_saved`)."""
    save_learner(
        learner,
        run.out / CHECKPOINT,
        metadata=state_of(run, emulator_state),
        arrays=history_arrays(run),
    )
    run.mark_saved()


def load_checkpoint(run: SurfaceRun, checkpoint: Path) -> dict[str, Any]:
    """Restore the run from ``checkpoint`` (the learner aside); return the emulators' state.

    Raises:
        StateFileError: the file is missing, damaged or of an unreadable version.
    """
    state = load_learner(checkpoint)[1]
    restore(run, state, load_extra_arrays(checkpoint))
    run.mark_saved()
    emulator: dict[str, Any] = state["emulator"]
    return emulator


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
        config = _as_started(config, metadata, copy)
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


def _as_started(config: CellConfig, metadata: dict[str, Any], copy: Path) -> CellConfig:
    """The config a resumed run started with: its zero check as it ran.

    A checkpoint from before the zero check was on by default holds no ``zero_check``:
    unless its config copy set it, that run ran without one, and goes on so.
    """
    zero_check = metadata.get("zero_check")
    if zero_check is None:
        table = tomllib.loads(copy.read_text()) if copy.exists() else {}
        zero_check = bool(table.get("task", {}).get("zero_check", False))
    if zero_check == config.task.zero_check:
        return config
    return dataclasses.replace(config, task=dataclasses.replace(config.task,
                                                                zero_check=zero_check))
