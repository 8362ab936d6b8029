"""A burst's record: statistics of its compensated normal force (N) and its time span (s)."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from forcelearn.devices import WrenchSample
from forcelearn.filtering.kalman import ForceFilterConfig
from forcelearn.records import BurstRecord


def burst_record(config: ForceFilterConfig, samples: Sequence[WrenchSample], filtered_n: float,
                 start_s: float) -> BurstRecord:
    """Statistics of a burst's compensated normal force (N) and its time span (s).

    The burst starts at the cell time of the last wait (the first sample is
    requested then); its span is the sensor's own time between its samples
    when the sensor tells it, else the filter's sample period per sample.
    """
    wrenches = np.array([s.wrench for s in samples], dtype=float)
    normal = config.normal_force(wrenches)
    gaps = [s.sensor_dt_s for s in samples[1:]]
    span = (
        float(sum(g for g in gaps if g is not None)) if all(g is not None for g in gaps)
        else (len(samples) - 1) * config.sample_period_s
    )
    mean = wrenches.mean(axis=0)
    return BurstRecord(
        mean_n=float(normal.mean()),
        std_n=float(normal.std()),
        first_n=float(normal[0]),
        last_n=float(normal[-1]),
        count=len(samples),
        start_s=start_s,
        span_s=span,
        filtered_n=float(filtered_n),
        wrench_mean=(float(mean[0]), float(mean[1]), float(mean[2]),
                     float(mean[3]), float(mean[4]), float(mean[5])),
    )
