"""Replay a run's recorded commands on the twin's wire-level emulated cell, open loop.

The twin's config is opened as CI runs it (:class:`~forcelearn.site.CellSession`:
the emulated controller and sensor behind the same drivers, limits and watchdog
as a real cell), and every recorded move is sent again in order: each trial's
probe, approach, step and retreat poses, a settle where the run settled, a
probe's dwell as long as the run held it, the tares where the run tared, and a
burst of as many samples as the run read after each move. The bursts read are
the replay's force. A recorded pose farther than ``safety.max_step_mm`` from where
the cell is (the first one, from the emulated arm's home) is reached in steps
within the limit, as a run moves to its start. Only an emulated cell is driven: a
config that names a real robot or sensor is refused before any device opens
(:class:`ReplayRefused`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from forcelearn.devices import Pose
from forcelearn.errors import ConfigError
from forcelearn.records import BurstRecord, MoveRecord, StepRecord, TareRecord, TrialRecords
from forcelearn.site.config import CellConfig

DWELL_FLOOR_S = 1e-6
"""A probe dwell shorter than this (s) is not held again."""


class ReplayRefused(ConfigError):
    """The replay was asked to drive a real device; it drives only emulated cells."""


@dataclass
class _Bursts:
    """Collects the cell's burst records (a :class:`~forcelearn.records.CellRecorder`)."""

    bursts: list[BurstRecord] = field(default_factory=list)

    def on_move(self, move: MoveRecord) -> None:
        """Moves are not needed."""

    def on_burst(self, burst: BurstRecord) -> None:
        """Keep the burst."""
        self.bursts.append(burst)

    def on_tare(self, tare: TareRecord) -> None:
        """Tares are not needed."""


def check_emulated(config: CellConfig) -> None:
    """Raise :class:`ReplayRefused` unless both the robot and the sensor are emulated."""
    real = [name for name, emulated in (("robot", config.robot_emulated),
                                        ("sensor", config.sensor_emulated)) if not emulated]
    if real:
        source = config.source or "the config"
        raise ReplayRefused(
            f"{source} names a real {' and '.join(real)}: replay drives the run's recorded "
            "commands open loop and only ever onto an emulated cell; give the twin's config "
            "(forcelearn twin --out twin.toml), or use --model forward to predict without a cell"
        )


def _is_dwell(step: StepRecord, previous: StepRecord | None) -> bool:
    """A probe's re-read after its dwell: the pose held, its times all the burst's start."""
    move = step.move
    return (previous is not None and move.commanded_mm == previous.move.commanded_mm
            and move.start_s == move.in_position_s == move.settled_s)


def replay_trials(records: list[TrialRecords], config: CellConfig,
                  seed: int = 0) -> list[list[float]]:
    """The burst means (N) the twin's emulated cell reads for every recorded step, in order.

    One list per trial of ``records`` (in order), one entry per step (NaN where the
    run read no burst). Raises :class:`ReplayRefused` for a real cell; a safety limit
    (force, step, workspace, stale sensor) stops the replay with the drivers' own
    typed error, as it would stop a run.
    """
    check_emulated(config)
    from forcelearn.site import CellSession

    orientation = config.task.orientation
    max_step_mm = config.safety.max_step_mm
    out: list[list[float]] = []
    with CellSession(config, seed=seed) as session:
        cell = session.cell
        assert cell is not None  # an open session has its cell
        collector = _Bursts()
        cell.recorder = collector
        for trial in sorted(records, key=lambda t: t.trial):
            tares = sorted(trial.tares, key=lambda t: t.time_s)
            cell.sync()
            cell.reset_filter()
            means: list[float] = []
            previous: StepRecord | None = None
            for step in trial.steps:
                while tares and tares[0].time_s <= step.move.start_s:
                    tares.pop(0)
                    cell.tare(config.task.tare_max_reading_n)
                move = step.move
                if _is_dwell(step, previous) and previous is not None:
                    hold = move.start_s - previous.move.settled_s
                    if previous.burst is not None:
                        hold -= previous.burst.span_s
                    if hold > DWELL_FLOOR_S:
                        cell.time_s = cell.robot.wait_in_position(cell.move_timeout_s, hold)
                else:
                    target = Pose(*move.commanded_mm, orientation)
                    here = cell.pose.position_mm
                    if math.dist(tuple(here), move.commanded_mm) > max_step_mm:
                        # not a recorded step (the replay's first pose, from the cell's home):
                        # get there as a run would, in steps within the limit
                        cell.move_in_steps(target, max_step_mm, guard_force=True)
                    else:
                        cell.move_to(target, settle=move.settled_s > move.in_position_s)
                mean = math.nan
                if step.burst is not None:
                    before = len(collector.bursts)
                    cell.measure_force_n(step.burst.count)
                    if len(collector.bursts) > before:
                        mean = collector.bursts[-1].mean_n
                means.append(mean)
                previous = step
            for _ in tares:
                cell.tare(config.task.tare_max_reading_n)
            out.append(means)
        cell.recorder = None
    return out
