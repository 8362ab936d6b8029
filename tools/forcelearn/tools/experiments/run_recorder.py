"""The run's :class:`~forcelearn.records.CellRecorder`: gathers one trial's moves, bursts, tares.

The cell hands it every waited move, every burst and every tare as they
happen; the cell's :attr:`~forcelearn.cell.Cell.stage` (set by the task) says
what each move was for. :meth:`TrialRecorder.take` hands the trial's records
over when the trial ends (the run engine then writes them) and starts the next.
"""

from __future__ import annotations

import dataclasses
import math

from forcelearn.cell import Cell
from forcelearn.records import BurstRecord, MoveRecord, StepRecord, TareRecord, TrialRecords

_Pending = tuple[str, int, MoveRecord, BurstRecord | None]


class TrialRecorder:
    """Collects one trial's records from a :class:`~forcelearn.cell.Cell` (a ``CellRecorder``)."""

    def __init__(self, cell: Cell) -> None:
        self.cell = cell
        self._steps: list[_Pending] = []
        self._tares: list[TareRecord] = []

    def on_move(self, move: MoveRecord) -> None:
        """A move ended (in position and settled): a step of the present stage."""
        kind, index = self.cell.stage
        self._steps.append((kind, index, move, None))

    def on_burst(self, burst: BurstRecord) -> None:
        """A burst was read: it belongs to the last move, or stands alone after a burst."""
        if self._steps and self._steps[-1][3] is None:
            kind, index, move, _ = self._steps[-1]
            self._steps[-1] = (kind, index, move, burst)
            return
        # a second burst without a move in between: a step that did not move
        kind, index = self.cell.stage
        time_s = self.cell.time_s
        here = self.cell.known_pose  # never an exchange with the robot for a record
        position = (
            (float(here.x_mm), float(here.y_mm), float(here.z_mm)) if here is not None
            else (math.nan, math.nan, math.nan)
        )
        still = MoveRecord(position, (math.nan,) * 3, time_s, time_s, time_s)
        self._steps.append((kind, index, still, burst))

    def on_tare(self, tare: TareRecord) -> None:
        """A tare was done or refused."""
        self._tares.append(tare)

    def take(self, trial: int) -> TrialRecords:
        """The records since the last take, as trial ``trial``'s; starts afresh."""
        records = TrialRecords(
            trial=trial,
            steps=[StepRecord(trial, index, kind, move, burst)
                   for kind, index, move, burst in self._steps],
            tares=[dataclasses.replace(tare, trial=trial) for tare in self._tares],
        )
        self.discard()
        return records

    def discard(self) -> None:
        """Forget what was gathered (a trial that did not end)."""
        self._steps, self._tares = [], []
