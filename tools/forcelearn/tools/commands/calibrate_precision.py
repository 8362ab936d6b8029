"""How long ``forcelearn calibrate`` measures: until the centre of mass is known well enough.

A light tool's moments are small against the sensor's noise and bias drift: one
pass over the orientations leaves its centre of mass known to a millimetre or
two (a 0.17 kg tool 167 mm off a JR3's axis: 2.3 mm RMS), a heavy tool's to a
few hundredths. So after the first pass the fit (generalised least squares,
the bias a random walk about its piecewise-linear fit, :mod:`forcelearn.calibration.drift`)
gives the centre of mass's RMS error ``sigma``; while it is above the target,
a third of the tolerance ``1 mm + 0.5 % |c|``, the pass is repeated, as many
times as the design predicts it takes (the same orientations and revisits,
their times extrapolated from the first pass), at most ``max_cycles`` passes
in all (default 16). The drift, not the noise, limits a light tool (a pose's 400 samples
average the noise to 0.01 N, while the bias walks 0.04 N during the 3.5 s
turn between two poses), so averaging longer at each pose buys little: only
more poses do.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from forcelearn.calibration.drift import (
    TARGET_FRACTION,
    DriftModel,
    com_tolerance_mm,
    drift_variance,
    predicted_com_std_mm,
    whitener,
)
from forcelearn.calibration.fit import REVISIT_DEG, bias_knots, design_with_drift
from forcelearn.calibration.model import MM_PER_M, Quaternion, ToolLoad, sensor_quaternion

Measured = tuple[str, Quaternion, np.ndarray, int, float, np.ndarray]
"""One measured pose: name, orientation reached, mean wrench, samples, time read (s) and the
variance of its mean (6,)."""
BLOCKS = 10
"""Blocks a pose's read is cut into to estimate the variance of its mean."""


def mean_variance(samples: list[Any], std: np.ndarray) -> np.ndarray:
    """Variance of a read's mean (6,), N^2 and (N*m)^2.

    From its block means (the adapter filter's correlation counted), at least
    the independent samples' ``std^2 / n``.
    """
    w = np.array([s.wrench for s in samples], dtype=float)
    floor = np.asarray(std, dtype=float) ** 2 / max(len(w), 1)
    if len(w) < 2 * BLOCKS:
        return floor
    blocks = np.array([b.mean(axis=0) for b in np.array_split(w, BLOCKS)])
    estimate: np.ndarray = np.maximum(blocks.var(axis=0, ddof=1) / BLOCKS, floor)
    return estimate


def drift_model(measured: list[Measured]) -> DriftModel:
    """The pose means' variances and the bias walk's rate estimated from the revisits."""
    mean_var = np.array([m[5] for m in measured])
    rate = drift_variance([m[1] for m in measured], np.array([m[4] for m in measured]),
                          np.array([m[2] for m in measured]), mean_var,
                          math.cos(math.radians(REVISIT_DEG) / 2))
    return DriftModel(mean_var, rate)


def com_sigma_mm(tool: ToolLoad) -> float:
    """RMS of the centre of mass's error norm (mm) the fit states."""
    return float(np.linalg.norm(tool.com_std_mm))


def target_mm(tool: ToolLoad) -> float:
    """The sigma aimed at: a third of 1 mm + 0.5 % of the centre of mass's distance (mm)."""
    return TARGET_FRACTION * com_tolerance_mm(tool.com_mm)


def predicted_after(measured: list[Measured], cycle: list[Measured], extra: int,
                    tool: ToolLoad, limit: float) -> float:
    """The centre of mass's RMS error (mm) predicted after ``extra`` more passes of ``cycle``.

    Each pass is ``cycle`` (orientations and mean variances) at its first pass's
    times, shifted to start where the measurements end.
    """
    model = drift_model(measured)
    quaternions = [m[1] for m in measured]
    times = [m[4] for m in measured]
    mean_var = [m[5] for m in measured]
    start = cycle[0][4]
    offsets = [m[4] - start for m in cycle[1:]]
    for _ in range(extra):
        end = times[-1]
        quaternions += [m[1] for m in cycle[1:]]
        times += [end + o for o in offsets]
        mean_var += [m[5] for m in cycle[1:]]
    t = np.array(times)
    knots = bias_knots(quaternions, t, limit if extra == 0 else math.inf)  # more passes: as the
    # first's knots, repeated (conditioned as well; the check's SVD is the costly part)
    design = design_with_drift([sensor_quaternion(q, tool.mounting_quaternion)
                                for q in quaternions], t, knots)
    white = whitener(t, knots, DriftModel(np.array(mean_var), model.walk_var_per_s))
    mc = np.asarray(tool.com_mm) / MM_PER_M * tool.mass_kg
    return predicted_com_std_mm(design, white, tool.mass_kg, mc)


def passes_needed(measured: list[Measured], cycle: list[Measured], tool: ToolLoad,
                  most: int, limit: float) -> int:
    """The fewest more passes (1..most) predicted to bring sigma under the target; else most.

    The prediction is scaled as the fit's stated sigma is to its own (at least 1),
    and searched by bisection (sigma falls with every pass).
    """
    goal = target_mm(tool)
    scale = max(1.0, com_sigma_mm(tool) / predicted_after(measured, cycle, 0, tool, limit))
    low, high = 0, most  # low misses the goal; high meets it, or is the most allowed
    while high - low > 1:
        middle = (low + high) // 2
        if scale * predicted_after(measured, cycle, middle, tool, limit) <= goal:
            high = middle
        else:
            low = middle
    return high


__all__ = ["Measured", "com_sigma_mm", "drift_model", "mean_variance", "passes_needed",
           "predicted_after", "target_mm"]
