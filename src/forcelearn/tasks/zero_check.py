"""The zero check in free space: one rule for the §5 run, the path task and the Gym env.

:meth:`forcelearn.cell.Cell.check_zero` reads a burst in free space and, within
its bound, takes the burst's mean as a zero *in software* (the sensor's own zero,
and the calibration's bias taken with it at the last tare's orientation, are left
as they are: a tool turned since then reads right, see docs/path.md).
:func:`check_zero` reads once more before it reports a moved zero.

The bound is :data:`ZERO_CHECK_SIGMAS` sigma of what a fault-free check reads
(:func:`zero_check_bound`: the burst's own noise, the zero's, the bias's drift
since the zero).
"""

from __future__ import annotations

import logging

from forcelearn.cell import Cell

log = logging.getLogger(__name__)

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


def check_zero(cell: Cell) -> tuple[float, float]:
    """The zero check here, in free space: (reading N, bound N).

    A check beyond the bound reads once more (a noise outlier does not repeat). Within the
    bound the burst's mean becomes the software zero (as ``Cell.check_zero``);
    beyond it nothing is zeroed and the caller voids what was read since the last zero.
    """
    force, bound = cell.check_zero(lambda std: zero_check_bound(cell, std))
    if abs(force) > bound:  # a moved zero reads so again; an outlier of the noise does not
        log.info("zero check read %.2f N (bound %.2f N): reading once more", force, bound)
        force, bound = cell.check_zero(lambda std: zero_check_bound(cell, std))
    return force, bound
