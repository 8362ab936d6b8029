"""The forward model by groups of rows of like length predicts what it does on the padded rows.

An identification's one long row padded every trial's row to its length (hidden cell 15 of
seed 1: 19 ms a prediction stacked, 7 ms by groups).
"""

from __future__ import annotations

import numpy as np

from forcelearn.emulators.physics.sponge import SpongeParams
from forcelearn.records import TrialRecords
from forcelearn.tools.twin import forward
from forcelearn.tools.twin.arrays import stack, to_arrays
from forcelearn.tools.twin.rowgroups import GroupedForward, row_groups
from forcelearn.tools.twin.setup import base_arm
from forcelearn.tools.twin.simulate import DOWN, SimulatedRun, simulate_run

READING = forward.Reading.of(DOWN, 1, -1.0)
ARM = base_arm()  # the emulator's defaults


def test_grouped_predictions_equal_the_padded_ones() -> None:
    """A long row (six trials' moves in one) beside short ones: the same burst means."""
    records = simulate_run(SimulatedRun(trials=6, steps=6), seed=3)
    long_row = TrialRecords(-2, [s for t in records for s in t.steps])
    data = stack(to_arrays([long_row]), to_arrays(records))
    groups = row_groups(data)
    assert [g.tolist() for g in groups] == [list(range(1, 7)), [0]]
    grouped = GroupedForward(data, ARM)
    shape, path = forward.motion_shape(data, ARM), forward.ToolPath(data, ARM)  # as fitted
    for sponge in (SpongeParams(), SpongeParams(stiffening_exponent=1.3, hysteresis_loss=0.2,
                                                relaxation_ratio=0.5, relaxation_time_s=0.3)):
        expected = forward.predict_means(data, sponge, ARM, READING, shape, path)
        predicted = grouped.predict(sponge, READING)
        assert np.array_equal(np.isnan(predicted), np.isnan(expected))
        assert np.allclose(predicted, expected, equal_nan=True, rtol=1e-12, atol=1e-12)
