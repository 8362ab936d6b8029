"""The run's side: hooks that feed the live model and the journal, and the metas of the tasks.

A hook does a lock, a few appends and (with a journal) one line written to
the page cache of the OS: it never waits for a page or a network.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

from forcelearn.learning import SRVLearner
from forcelearn.tools.live.journal import JournalWriter
from forcelearn.tools.live.model import LiveMeta, LiveModel
from forcelearn.trainer import TrialLog, TrialRecord

if TYPE_CHECKING:
    from forcelearn.site.config import CellConfig
    from forcelearn.tools.experiments.contour import ContourConfig

RowExtras = Callable[[dict[str, float]], dict[str, float]]


class LivePublisher:
    """Publishes a run to a model (for a live page) and/or a journal (for ``view``).

    Args:
        meta: the run's facts (also the journal's first line).
        model: the model a live server reads, or None.
        journal: the journal to append to, or None.
        extras: derived figures added to a copy of each step row (e.g. mean Y in mm).
    """

    def __init__(
        self,
        meta: LiveMeta,
        model: LiveModel | None = None,
        journal: JournalWriter | None = None,
        extras: RowExtras | None = None,
    ):
        self.meta, self.model, self.journal, self.extras = meta, model, journal, extras
        self._started = time.perf_counter()
        if journal is not None:
            journal.write({"t": "meta", "w": 0.0, "meta": meta.to_json()})

    def wall_s(self) -> float:
        """Seconds since the publisher started."""
        return time.perf_counter() - self._started

    def on_step(self, trial: int, phase: str, row: dict[str, float]) -> None:
        """The trainer's ``on_step`` hook."""
        if self.extras is not None:
            row = {**row, **self.extras(row)}
        wall = self.wall_s()
        if self.model is not None:
            self.model.step(trial, phase, row, wall)
        if self.journal is not None:
            self.journal.write({"t": "step", "w": wall, "trial": trial, "phase": phase, "row": row})

    def on_trial(self, record: TrialRecord, learner: SRVLearner) -> None:
        """After a trial (the learner's phase is already updated)."""
        switched = learner.phase.name.lower() != record.phase
        wall = self.wall_s()
        if self.model is not None:
            self.model.trial(record, switched, wall)
        if self.journal is not None:
            line = {"t": "trial", "w": wall, "record": record.__dict__, "switched": switched}
            self.journal.write(line)

    def on_trial_log(self, record: TrialRecord, log: TrialLog, learner: SRVLearner) -> None:
        """The trainer's ``on_trial`` hook (with the step log, unused here)."""
        self.on_trial(record, learner)

    def event(self, kind: str, message: str) -> None:
        """A safety event or incident (the error that stopped the run, Ctrl-C)."""
        wall = self.wall_s()
        if self.model is not None:
            self.model.event(kind, message, wall)
        if self.journal is not None:
            self.journal.write({"t": "event", "w": wall, "kind": kind, "message": message})

    def finish(self, error: str | None = None) -> None:
        """The run ended; closes the journal."""
        wall = self.wall_s()
        if self.model is not None:
            self.model.finish(wall, error)
        if self.journal is not None:
            self.journal.write({"t": "end", "w": wall, "error": error})
            self.journal.close()


def surface_meta(config: CellConfig, trials_target: int, source: str = "live") -> LiveMeta:
    """The meta of a surface run: task facts and the devices it drives."""
    robot_kind, sensor_kind = config.robot_device, config.sensor_device
    robot = (f"emulated {robot_kind.label} controller" if config.robot_emulated
             else robot_kind.location(config))
    sensor = (f"emulated {sensor_kind.label}" if config.sensor_emulated
              else sensor_kind.location(config))
    return LiveMeta(
        task="surface",
        desired_force_n=config.task.desired_force_n,
        steps_per_trial=config.task.steps_per_trial,
        trials_target=trials_target,
        devices=(f"robot: {robot}", f"sensor: {sensor}"),
        source=source,
    )


def surface_extras(run: Any) -> RowExtras:
    """Adds the row's Y figures in mm: mean μ, the map's centre and its wear shift.

    ``mean_y_mm`` (the learner's mean μ as a Y command: Fig. 12's solid line),
    ``map_centre_y_mm`` (the output map's centre at the step, its wear shift
    included) and ``map_shift_mm`` (how far the map's centre has moved: the wear it followed
    plus its re-centring on the learner).

    ``run`` is the ``SurfaceRun``: its output map is known only once the run has
    probed the surface (or restored the probe), so it is read at each row.
    """
    from forcelearn.tasks.surface import SurfaceYOutput

    spec = run.config.task
    fallback = SurfaceYOutput(
        spec.fallback_centre_y_mm, spec.fallback_scale_mm, spec.fallback_offset_mm
    )
    step_mm = abs(spec.z_step_mm)

    def extras(row: dict[str, float]) -> dict[str, float]:
        choice = getattr(run, "output_map", None)
        output = choice.output(step_mm) if choice is not None else fallback
        if choice is not None:  # a map that follows wear: where it has moved to
            output.shift_mm = float(getattr(run, "map_shift_mm", 0.0))
            output.recentre_mm = float(getattr(run, "map_recentre_mm", 0.0))
        step = int(row["step"]) - 1
        return {
            "mean_y_mm": output.command_at_step(row["mean_0"], step),
            "map_centre_y_mm": output.command_at_step(0.0, step),
            "map_shift_mm": output.displacement_mm,
        }

    return extras


def contour_meta(config: ContourConfig) -> LiveMeta:
    """The meta of a contour simulation: task facts and the disc the arm presses on."""
    geometry = config.geometry
    return LiveMeta(
        task="contour",
        desired_force_n=config.task.desired_force_n,
        steps_per_trial=config.task.steps_per_trial,
        trials_target=config.trials,
        devices=("simulated two-link arm (paper §4)",),
        geometry={
            "centre_m": list(geometry.centre_m),
            "radius_m": geometry.radius_m,
            "link1_m": getattr(geometry, "link1_m", None),
            "link2_m": getattr(geometry, "link2_m", None),
        },
    )


def describe_error(exc: BaseException) -> tuple[str, str]:
    """(kind, message) of the exception that stopped a run."""
    if isinstance(exc, KeyboardInterrupt):
        return "Interrupted", "Ctrl-C: the robot was stopped"
    return type(exc).__name__, str(exc)


__all__ = [
    "LivePublisher",
    "contour_meta",
    "describe_error",
    "surface_extras",
    "surface_meta",
]
