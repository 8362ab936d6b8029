"""The path task's probe pass and the learner's warm start from it.

Before learning, one pass over the path with a plain correction, no learning:

1. at the first point, from the approach pose, the tool steps in along the
   force axis (``CONTACT_STEP_MM``) until it reads the desired force (or reaches
   ``max_deviation_mm``); a straight line through the readings above the
   contact threshold gives the foam's **stiffness** k (N/mm) and where contact
   begins;
2. at every point k it presses at the offset the previous point's error asks
   for, ``o_k = o_{k-1} + (F_d − F_{k-1}) / k``, clipped to ±``max_deviation_mm``,
   and reads the force F_k, as a pass would (same moves, same pace);
3. it retreats.

Each point's **target offset** is ``o_k + (F_d − F_k) / k``: the learner's mean μ
starts there (in action units, through the output's scale), and its predicted
evaluation r̂ at what the linear step does not know: ``STIFFNESS_SPREAD`` of the
error the step corrects, in tolerances (at least ``MIN_R_HAT``). A probe pass
that did not settle (its errors above ``UNSETTLED_RMS_SHARE`` of the force: a
hysteretic foam, whose force depends on the way in) gets its targets smoothed
along the path and its output scale from the stiffness met between points. A point where
the probe lost contact gets the target interpolated from its neighbours along
the path and r̂ = 1 (the widest search). The output scale is
``OUTPUT_SCALE_SHARE`` · tolerance / k mm per action unit.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.ndimage import convolve1d

from forcelearn.errors import SafetyStop
from forcelearn.learning import SRVLearner
from forcelearn.tasks.path import PathTask

STIFFNESS_SPREAD = 0.15
"""Relative error of the probe's one stiffness at another point (assumption: the foam's
stiffness varies ±15 % over a part, the default sponge's variation)."""
MIN_R_HAT = 0.05
"""Least predicted evaluation the warm start gives a box (the probe is never exact)."""
OUTPUT_SCALE_SHARE = 0.25
"""The output scale in tolerances per unit of action, over k: the learner's widest search
(σ_max = 0.5) moves the force by an eighth of the tolerance. Once the probe's start is close
the learner's steps of μ are driven by the force's noise; a smaller scale makes that random
walk smaller (assumption, chosen with the wear shift on: the study in docs/path.md measures
the result; it was not tuned against other shares)."""
FALLBACK_COMPRESSION_MM = 10.0
"""Compression assumed for the desired force when the probe cannot fit a stiffness, mm."""
UNSETTLED_RMS_SHARE = 0.10
"""A probe pass whose force error over the points in contact has an RMS above this share of the
desired force did not settle: on a foam whose force depends on the way in (hysteresis: a point
pressed deeper than the last meets the loading branch, the next, shallower, the unloading one)
the point-to-point correction jumps between branches and its targets alternate with it. Its
targets are then smoothed along the path (:data:`SMOOTHING`). Fault-free probes of the example
parts (no hysteresis) leave 0.12-0.63 N against the 1.96 N this gives at 19.6 N; a part with
h = 0.2 left 6.9 N."""
SMOOTHING = (1.0 / 16, 4.0 / 16, 6.0 / 16, 4.0 / 16, 1.0 / 16)
"""Weights of the smoothing along the path (binomial: removes a point-to-point alternation
exactly, keeps a trend along the path)."""


class ProbeFailed(SafetyStop):
    """The probe pass found no contact anywhere on the path."""


@dataclass(frozen=True)
class PathProbe:
    """What the probe pass measured and the warm start it gives (per point, mm and N)."""

    stiffness_n_per_mm: float
    contact_offset_mm: float
    """Offset at point 0 where the force begins (the line's zero), mm."""
    offsets_mm: tuple[float, ...]
    forces_n: tuple[float, ...]
    targets_mm: tuple[float, ...]
    r_hats: tuple[float, ...]
    lost: tuple[int, ...]
    """Points where the probe read less than the contact threshold."""

    tolerance_n: float
    """The task's tolerance (r = 1), N."""
    pass_stiffness_n_per_mm: float | None = None
    """An unsettled probe's stiffness between consecutive points (force change over offset
    change, least squares), N/mm, when above k: a hysteretic foam meets it whenever the
    offset reverses from one point to the next. None: a settled probe."""

    @property
    def scale_mm(self) -> float:
        """Output scale: mm per action unit (OUTPUT_SCALE_SHARE · tolerance / k).

        On an unsettled probe k is the stiffer of k and ``pass_stiffness_n_per_mm``: the
        learner's search from point to point then moves the force as little as on a foam
        without hysteresis.
        """
        k = max(self.stiffness_n_per_mm, self.pass_stiffness_n_per_mm or 0.0)
        return OUTPUT_SCALE_SHARE * self.tolerance_n / k


def fit_stiffness(readings: list[tuple[float, float]], contact_n: float,
                  desired_n: float) -> tuple[float, float]:
    """(k N/mm, contact offset mm) from (offset, force) readings above ``contact_n``."""
    pressed = [(o, f) for o, f in readings if f >= contact_n]
    if len(pressed) >= 2:
        slope, intercept = np.polyfit([o for o, _ in pressed], [f for _, f in pressed], 1)
        if slope > 0:
            return float(slope), float(-intercept / slope)
    k = desired_n / FALLBACK_COMPRESSION_MM
    last_offset, last_force = readings[-1]
    return k, last_offset - max(last_force, 0.0) / k


def probe_pass(task: PathTask) -> PathProbe:
    """Run the probe pass on the task's cell (module docstring)."""
    spec, cell = task.spec, task.cell
    desired, limit = spec.desired_force_n, spec.max_deviation_mm
    cell.sync()
    task.return_to_start()
    task.tare()
    readings = task.find_contact(until_n=desired)
    k, contact = fit_stiffness(readings, spec.contact_force_n, desired)
    task.stiffness_n_per_mm = k
    task.contact_offset_mm = contact
    offset, force = readings[-1]
    offsets, forces = [], []
    for point in range(len(task.points)):
        cell.stage = ("probe", point + 1)
        if force >= spec.contact_force_n:
            offset = min(max(offset + (desired - force) / k, -limit), limit)
        task.move_to_point(point, offset, pressing=True)
        force = cell.measure_force_n()
        offsets.append(offset)
        forces.append(force)
    task.retreat()
    found = np.array(forces) >= spec.contact_force_n
    if not found.any():
        raise ProbeFailed("the probe pass met no contact anywhere on the path: check the path's "
                          "frame (wobjdata), task.force_axis and task.max_deviation_mm")
    index = np.arange(len(forces))
    raw = np.array(offsets) + (desired - np.array(forces)) / k
    targets = np.interp(index, index[found], raw[found])
    errors = np.array(forces)[found] - desired
    pass_k = None
    if np.sqrt(np.mean(errors**2)) > UNSETTLED_RMS_SHARE * desired and len(targets) > 2:
        targets = convolve1d(targets, SMOOTHING, mode="nearest")  # the branches' mean
        both = found[1:] & found[:-1]
        d_offset, d_force = np.diff(offsets)[both], np.diff(forces)[both]
        if np.any(d_offset != 0):
            pass_k = float(d_force @ d_offset / (d_offset @ d_offset))
            pass_k = pass_k if pass_k > k else None
    targets = np.clip(targets, -limit, limit)
    evaluation = spec.evaluation
    r_hats = np.where(found, [max(MIN_R_HAT, evaluation.ratio(STIFFNESS_SPREAD * (desired - f)))
                              for f in forces], 1.0)
    return PathProbe(k, contact, tuple(offsets), tuple(forces), tuple(float(t) for t in targets),
                     tuple(float(r) for r in r_hats),
                     tuple(int(i) for i in index[~found]), spec.tolerance, pass_k)


def warm_start(learner: SRVLearner, probe: PathProbe) -> None:
    """Every point's box: μ at the probe's target (action units), r̂ at its uncertainty."""
    for point, (target, r_hat) in enumerate(zip(probe.targets_mm, probe.r_hats, strict=True)):
        box = learner.grid.index(np.array([float(point)]))
        learner.weights[box] = target / probe.scale_mm
        learner.predictions[box] = min(r_hat, 1.0) if math.isfinite(r_hat) else 1.0
