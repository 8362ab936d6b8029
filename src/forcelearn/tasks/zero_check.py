"""The zero check in free space, for a tool that turns (the path task) and for the Gym env.

:meth:`forcelearn.cell.Cell.check_zero` reads a burst in free space and, within
its bound, takes the burst's mean as a zero *in software* (the sensor's own zero
is left as it is). The calibration's bias belongs to the sensor's zero, taken at
the orientation of the last tare: a software zero must leave it there. The cell
re-derives it for the check's orientation (``zero_taken_at``), which is the same
on the §5 task (the tool never turns) but wrong by the tool's weight turned
between the two orientations on a path: every reading after it is off by that
difference, and the next tare's tool check raises ``ToolMismatch`` (measured on
the cylinder example: the tool turned 50 deg, see docs/path.md).
:func:`check_zero` keeps the calibration the sensor's zero was taken with.

The bound is :data:`ZERO_CHECK_SIGMAS` sigma of what a fault-free check reads
(:func:`zero_check_bound`: the burst's own noise, the zero's, the bias's drift
since the zero), as the §5 run's (:mod:`forcelearn.tools.experiments.fault_recovery`).
"""

from __future__ import annotations

from forcelearn.calibration.model import Calibration
from forcelearn.cell import Cell

ZERO_CHECK_SIGMAS = 5.0
"""The zero check's bound, in sigma of what a fault-free check reads (5, and a check beyond it
reads once more before it voids anything: fault-free checks measured about 1.2x the model's
sigma, and at 4 sigma without a second read fault-free runs voided good trials,
docs/fuzzing.md): the check burst's own noise (the filter's standard deviation of its mean),
the zero's (the last check's burst, or one sensor sample after a zero of the sensor's own) and
the bias's drift since the zero (``[filter] bias_drift_n_per_sqrt_s``)."""


def zero_check_bound(cell: Cell, burst_std_n: float) -> float:
    """The bound of a check burst of this standard deviation (N) on ``cell``, N.

    ZERO_CHECK_SIGMAS x sqrt(burst variance + the zero's variance + drift^2 x time since the zero).
    """
    sensor_sigma = cell.force_filter.measurement_variance_n2 ** 0.5
    zero_std = sensor_sigma if cell.zero_std_n is None else cell.zero_std_n
    drift = cell.force_filter.config.bias_drift_n_per_sqrt_s
    elapsed = max(cell.time_s - cell.zero_time_s, 0.0)
    variance = burst_std_n ** 2 + zero_std ** 2 + drift ** 2 * elapsed
    return float(ZERO_CHECK_SIGMAS * variance ** 0.5)


def keep_calibration(cell: Cell, calibration: Calibration | None) -> None:
    """Put back the calibration of the sensor's zero after a software zero re-derived it."""
    if calibration is not None and cell.calibration is not calibration:
        cell.calibration = calibration
        cell.compensation = calibration.compensation


def check_zero(cell: Cell) -> tuple[float, float]:
    """The zero check here, in free space: (reading N, bound N); the calibration kept.

    A check beyond the bound reads once more (a noise outlier does not repeat). Within the
    bound the burst's mean becomes the software zero (as ``Cell.check_zero``);
    beyond it nothing is zeroed and the caller voids what was read since the last zero.
    """
    calibration = cell.calibration
    try:
        force, bound = cell.check_zero(lambda std: zero_check_bound(cell, std))
        if abs(force) > bound:  # a moved zero reads so again; an outlier of the noise does not
            force, bound = cell.check_zero(lambda std: zero_check_bound(cell, std))
        return force, bound
    finally:
        keep_calibration(cell, calibration)
