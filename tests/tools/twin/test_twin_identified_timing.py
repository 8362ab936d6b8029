"""The moves' true in-position times come from the identification's arm when it has one.

``identify_fit.identified_arm``: the force model moves the tool with the identified arm, and
``arm.true_in_position_s`` must end each move when that arm (the emulator's) is in position,
not when the run's own timing fit, which explains its 44 ms poll windows with any arm, says.
"""

from __future__ import annotations

import math

import pytest

from forcelearn.emulators.physics.arm_motion import MotionParams
from forcelearn.records import BurstRecord, MoveRecord, StepRecord, TrialRecords
from forcelearn.tools.twin import identify_fit
from forcelearn.tools.twin.arm import ArmFit, _emulated_s, true_in_position_s
from forcelearn.tools.twin.arrays import to_arrays
from forcelearn.tools.twin.identify import Identification, IdentifyPlan
from forcelearn.tools.twin.identify_fit import TimingFit, identified_arm
from forcelearn.tools.twin.setup import base_arm

BAND = 0.1  # mm, the emulated arm's in-position band
PERIOD = 0.0435  # s, the computer link's status polls
CELL = {"start_delay_s": 0.12, "accel_mm_s2": 1000.0, "default_speed_mm_s": 100.0,
        "lag_s": 0.08}
"""The cell's arm (as the twin times it: the start delay counts the link's command time)."""
RUN_FIT = {"start_delay_s": 0.128, "accel_mm_s2": 6237.0, "default_speed_mm_s": 220.0,
           "lag_s": 0.090}
"""What a run's own timing fit found on hidden cell 09 of seed 1 (its moves within their
windows, its values far from the cell's)."""


def test_a_step_is_in_position_when_the_identified_arm_is(monkeypatch: pytest.MonkeyPatch
                                                          ) -> None:
    """A 1.16 mm step (an identification's hold step) ends when the cell's arm is in position."""
    step_mm, command = 1.157, 10.0
    params = MotionParams(speed_mm_s=CELL["default_speed_mm_s"], accel_mm_s2=CELL["accel_mm_s2"],
                          start_delay_s=CELL["start_delay_s"], lag_s=CELL["lag_s"],
                          in_position_mm=BAND, tick_s=0.004)
    true_s = command + _emulated_s(params, step_mm)  # the emulated arm itself
    recorded = true_s + 0.6 * PERIOD  # the poll that saw it
    steps = [StepRecord(0, 0, "step", MoveRecord((0.0, 10.0, 0.0), (0.0, 10.0, 0.0), 0.0, 1.0,
                                                 1.0), None),
             StepRecord(0, 1, "step", MoveRecord((0.0, 10.0 - step_mm, 0.0),
                                                 (0.0, 10.0 - step_mm, 0.0), command, recorded,
                                                 recorded),
                        BurstRecord(0.0, 0.05, 0.0, 0.0, 16, 0.015, recorded, 0.0))]
    data = to_arrays([TrialRecords(0, steps)])
    run = ArmFit(base_arm(), {n: math.inf for n in CELL}, 0.02, 40, period_s=PERIOD,
                 timing=RUN_FIT)
    fitted = TimingFit(CELL, {n: 1e-3 for n in CELL}, 0.001, 150)
    monkeypatch.setattr(identify_fit, "timing_of", lambda identification, band_mm: fitted)
    arm = identified_arm(run, Identification(IdentifyPlan(), [], []), BAND)
    run_s = float(true_in_position_s(data, run, BAND)[0, 1])
    assert abs(run_s - true_s) > 0.01  # the run's own fit: 15 ms late
    assert float(true_in_position_s(data, arm, BAND)[0, 1]) == pytest.approx(true_s, abs=0.003)
