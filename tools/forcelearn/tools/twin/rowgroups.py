"""The forward model on groups of rows of like length: the same predictions, less padding.

The fitted records are (rows, moves) arrays padded to the longest row, and the forward
model's cost grows with that width: an identification's one row of ~340 moves beside a
run's rows of ~100 made every prediction 4x the work (hidden cell 15 of seed 1: 19 ms
stacked, 5 ms for the run's rows alone, 2 ms for the identification's). Each row is a trial
or a probe point that starts from free space on its own (the forward model carries nothing
from one row to the next), so the rows are predicted in groups, each trimmed to its own
longest row, and put back in place.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from forcelearn.emulators.physics.sponge_law import SpongeParams
from forcelearn.tools.twin.arrays import RecordArrays
from forcelearn.tools.twin.forward import (
    MotionShape,
    Reading,
    ToolPath,
    motion_shape,
    predict_means,
)

LONG_FACTOR = 2.0
"""A row more than this many times the median row's length is predicted apart."""


def widths(data: RecordArrays) -> np.ndarray:
    """(T,) each row's length: one past its last recorded move."""
    last = data.valid.shape[1] - np.argmax(data.valid[:, ::-1], axis=1)
    result: np.ndarray = np.where(data.valid.any(axis=1), last, 0)
    return result


def trimmed(data: RecordArrays, rows: np.ndarray, width: int) -> RecordArrays:
    """Rows ``rows`` of ``data``, their moves cut to the first ``width``."""
    part = data.rows(rows)
    fields = {name: (value[:, :width] if value.ndim > 1 else value)
              for name, value in ((n, getattr(part, n)) for n in part.__dataclass_fields__)}
    return dataclasses.replace(part, **fields)


def row_groups(data: RecordArrays) -> list[np.ndarray]:
    """The rows in groups: those up to ``LONG_FACTOR`` x the median length, each longer alone.

    One group of all rows when none is longer.
    """
    width = widths(data)
    limit = LONG_FACTOR * float(np.median(width)) if width.size else 0.0
    long_rows = np.flatnonzero(width > limit)
    short = np.flatnonzero(width <= limit)
    return ([short] if short.size else []) + [np.array([r]) for r in long_rows]


class GroupedForward:
    """:func:`~forcelearn.tools.twin.forward.predict_means` of ``data`` for one arm, by groups."""

    def __init__(self, data: RecordArrays, arm: dict[str, float]) -> None:
        self.data, self.arm = data, arm
        self.parts: list[tuple[np.ndarray, RecordArrays, MotionShape, ToolPath]] = []
        width = widths(data)
        # the arm's motion of every move at once, then cut: a move's path is run over as
        # many ticks as the longest move of the set needs, so a group's own would differ
        whole = motion_shape(data, arm)
        for rows in row_groups(data):
            cut = max(1, int(width[rows].max()))
            part = trimmed(data, rows, cut)
            shape = MotionShape(whole.share[rows, :cut], whole.before_end_s[rows, :cut])
            self.parts.append((rows, part, shape, ToolPath(part, arm)))

    def predict(self, p: SpongeParams, reading: Reading) -> np.ndarray:
        """Predicted burst means (T, M), N; NaN where no burst was read."""
        out = np.full(self.data.mean_n.shape, np.nan)
        for rows, part, shape, path in self.parts:
            predicted = predict_means(part, p, self.arm, reading, shape, path)
            out[rows, :predicted.shape[1]] = predicted
        return out
