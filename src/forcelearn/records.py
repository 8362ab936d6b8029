"""What a run records so that its cell can be identified: every move, burst and tare.

These are plain values, written by the run engine (MCAP, docs/records.md) and read
back by ``forcelearn twin`` and ``forcelearn replay``. Times are the cell's clock
(the robot's time, s, as :attr:`forcelearn.cell.Cell.time_s`); positions in mm in
the robot's base frame; forces in N.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Protocol


@dataclass(frozen=True)
class MoveRecord:
    """One commanded move and how the robot carried it out.

    Attributes:
        commanded_mm: the target's (x, y, z), mm.
        reached_mm: the pose the robot reported once in position, (x, y, z) mm.
        start_s: cell time the command was sent, s.
        in_position_s: cell time the robot first reported in position, s.
        settled_s: cell time the settle dwell ended (the burst may start), s.
    """

    commanded_mm: tuple[float, float, float]
    reached_mm: tuple[float, float, float]
    start_s: float
    in_position_s: float
    settled_s: float


@dataclass(frozen=True)
class BurstRecord:
    """The burst of sensor samples read after a move (the normal force, sign applied).

    Attributes:
        mean_n: mean of the burst's normal force (compensated, unfiltered), N.
        std_n: its standard deviation (ddof 0), N.
        first_n: the first sample's normal force, N.
        last_n: the last sample's, N.
        count: samples in the burst.
        start_s: sensor time of the first sample on the cell clock, s.
        span_s: sensor time from the first to the last sample, s.
        filtered_n: the force filter's estimate the learner was given, N.
        wrench_mean: mean of the burst's compensated wrench in the sensor frame
            (Fx, Fy, Fz in N, Tx, Ty, Tz in N·m): friction along the motion shows here.
    """

    mean_n: float
    std_n: float
    first_n: float
    last_n: float
    count: int
    start_s: float
    span_s: float
    filtered_n: float
    wrench_mean: tuple[float, float, float, float, float, float] | None = None


@dataclass(frozen=True)
class StepRecord:
    """One move of a trial and the burst read after it.

    ``stage`` says what the move was for: ``"approach"`` (to the trial's start pose),
    ``"step"`` (a control step of the learner; ``index`` counts them from 1),
    ``"retreat"`` (back off the surface after the trial) or ``"probe"``.
    ``burst`` is None when no force was read after the move.
    """

    trial: int
    index: int
    stage: str
    move: MoveRecord
    burst: BurstRecord | None


@dataclass(frozen=True)
class TareRecord:
    """One tare of the sensor: where, when, and what it read before zeroing.

    Attributes:
        trial: the trial it preceded.
        time_s: cell time, s.
        position_mm: the robot's (x, y, z) at the tare, mm.
        reading_n: the normal force read just before zeroing, N.
        accepted: False when the tare was refused (reading too large).
    """

    trial: int
    time_s: float
    position_mm: tuple[float, float, float]
    reading_n: float
    accepted: bool


@dataclass
class TrialRecords:
    """Everything one trial recorded, in order."""

    trial: int
    steps: list[StepRecord] = field(default_factory=list)
    tares: list[TareRecord] = field(default_factory=list)


class CellRecorder(Protocol):
    """Receives the cell's records as they happen (the run engine writes them per trial)."""

    def on_move(self, move: MoveRecord) -> None:
        """A move finished (in position and settled)."""

    def on_burst(self, burst: BurstRecord) -> None:
        """A burst was read after the last move."""

    def on_tare(self, tare: TareRecord) -> None:
        """A tare was done or refused."""
