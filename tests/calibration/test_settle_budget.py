"""The settling wait counts the sensor's samples, not the host's seconds."""

from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np
import pytest

from forcelearn.errors import CalibrationError
from forcelearn.tools.experiments.calibration_plan import CalibrationPlan
from forcelearn.tools.experiments.calibration_run import READ_CHUNK, Calibrator


class _Swinging:
    """A sensor whose block means jump by 1 N every block: it never settles."""

    def __init__(self) -> None:
        self.read = 0

    def read_many(self, count: int) -> list[SimpleNamespace]:
        self.read += count
        level = float(self.read // count % 2)
        return [SimpleNamespace(wrench=np.full(6, level)) for _ in range(count)]


def test_a_reading_that_never_settles_is_refused_after_the_timeout_in_samples() -> None:
    """settle_timeout_s of samples at the sample period, whatever the host's speed."""
    plan = CalibrationPlan(settle_timeout_s=0.5)
    calibrator = object.__new__(Calibrator)
    sensor = _Swinging()
    calibrator.sensor, calibrator.plan, calibrator.sample_period_s = sensor, plan, 1e-3
    with pytest.raises(CalibrationError, match=r"did not settle within 0\.5 s"):
        calibrator._settle_reading(np.full(6, 0.01))
    blocks = math.ceil(plan.settle_timeout_s / calibrator.sample_period_s / READ_CHUNK)
    assert sensor.read == (blocks + 1) * READ_CHUNK
