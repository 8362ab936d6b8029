"""The burst filter's median and sample times (Python on a burst's few samples) are numpy's."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from forcelearn.devices import WrenchSample
from forcelearn.filtering.kalman import ForceFilterConfig
from forcelearn.filtering.step_filter import MoveAwareForceFilter, median

_VALUES = st.one_of(st.floats(allow_nan=True, allow_infinity=True),
                    st.sampled_from([0.0, -0.0, 1.5, -1.5, 1e308]))


@settings(max_examples=500, deadline=None)
@given(st.lists(_VALUES, min_size=1, max_size=40))
def test_median_is_numpys_to_the_bit(values: list[float]) -> None:
    """Odd and even counts, ties, signed zeros, infinities and NaN."""
    expected = np.median(np.array(values))
    assert np.float64(median(values)).tobytes() == np.float64(expected).tobytes()


@settings(max_examples=200, deadline=None)
@given(st.lists(st.one_of(st.none(), st.floats(1e-6, 0.01)), min_size=1, max_size=30))
def test_burst_times_are_the_cumulative_sum(steps: list[float | None]) -> None:
    """``burst_times_s`` is ``concatenate(([0], cumsum(dt)))``, the sample period where none."""
    config = ForceFilterConfig()
    samples = [WrenchSample(np.zeros(6), 0.0, i, sensor_dt_s=dt) for i, dt in enumerate(steps)]
    period = config.sample_period_s
    dts = [period if s.sensor_dt_s is None else s.sensor_dt_s for s in samples[1:]]
    expected = np.concatenate(([0.0], np.cumsum(dts)))
    got = MoveAwareForceFilter(config).burst_times_s(samples)
    assert got.dtype == expected.dtype and got.tobytes() == expected.tobytes()
