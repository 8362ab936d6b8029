"""The learner's start on the §5 task: from what the surface probe knows, or from nothing.

``run.learner_start`` (:data:`LEARNER_STARTS`):

* ``"probe"`` (the default): every box's mean μ starts at the action whose Y
  command is the probe's target, the Y where its fits (interpolated in Z)
  give the desired force at the step that box commands; every box's
  predicted evaluation r̂ starts at what the probe does not know there, in
  tolerances: k · σ_y (σ_y: the target's standard error from the fit's
  contact and stiffness errors), the fit's residual force, and the foam's
  relaxation the probe saw (its early reading above the relaxed one, as a
  share of the desired force: a pass reads between the two), in quadrature;
  so the search width σ = s(r̂) is that uncertainty. The learner then learns
  what the probe could not know (the relaxation at the pass's speed, the
  wear, the surface between probed points). With this start the probe also
  measures its ``refine_points`` (:func:`probe_and_map`'s ``refine``), so the
  path has the surface's waves. The target is where the sensor will read
  the desired force: the fits' forces are free of the sensor's bias, the
  task's readings carry it as it drifted over the probe (:func:`aimed_force_n`).
* ``"cold"``: μ = 0 (the map's centre) and r̂ = ``learner.initial_prediction``
  in every box: the §5 experiment as published, the learner finding the path
  by random search.

Box k is the box of the input the task gives before the step it commands:
the distance travelled x = k · |z_step| (:meth:`SurfaceTask.step` returns it),
whose command moves to step k + 1, at Z = start Z + (k + 1) · z_step, with the
output map's centre of step k (:meth:`SurfaceYOutput.centre_at`).
"""

from __future__ import annotations

import itertools
import math

import numpy as np

from forcelearn.errors import ConfigError
from forcelearn.learning import SRVLearner
from forcelearn.tasks.surface_fit import ProbeResult
from forcelearn.tasks.surface_map import SurfaceYOutput
from forcelearn.tasks.surface_spec import SurfaceTaskSpec

LEARNER_STARTS = ("probe", "cold")
"""``run.learner_start`` values."""
OLD_CHECKPOINT_START = "cold"
"""The start of a run whose checkpoint names none (written before the key existed)."""


def check_learner_start(value: object) -> str:
    """Return ``value`` if it is a known start, else raise :class:`ConfigError` naming the key."""
    if not isinstance(value, str) or value not in LEARNER_STARTS:
        raise ConfigError(
            f"run.learner_start = {value!r}: one of {', '.join(repr(v) for v in LEARNER_STARTS)} "
            "(\"probe\": the learner starts on the probe's path; \"cold\": μ = 0, the paper's §5)"
        )
    return value


def step_targets(probe: ProbeResult, task: SurfaceTaskSpec) -> tuple[np.ndarray, np.ndarray]:
    """Per step of a trial: the probe's target Y (mm) and its uncertainty as an evaluation.

    The uncertainty r̂ = |(k · σ_y, residual, relaxation)| / tolerance, with
    σ_y² = σ_c² + (F / k²)² σ_k² (target y = y_c − F / k) and the relaxation
    :func:`relaxation_share` × F, interpolated in Z between the probed points
    like the target.
    """
    targets = probe.target_path_mm(task, aimed_force_n(probe, task))
    z_steps = task.start_mm[2] + task.z_step_mm * np.arange(1, task.steps_per_trial + 1)
    force = task.desired_force_n
    evaluation = task.evaluation
    relaxed = relaxation_share(probe) * force
    by_z: dict[float, list[float]] = {}
    for fit in probe.fits:
        k = fit.stiffness_n_per_mm
        sigma_y = math.hypot(fit.contact_y_std, force / k**2 * fit.stiffness_std)
        r_hat = evaluation.ratio(math.hypot(k * sigma_y, fit.residual_rms_n, relaxed))
        by_z.setdefault(fit.z_mm, []).append(r_hat)
    z_fit = np.array(sorted(by_z))
    r_fit = np.array([float(np.mean(by_z[z])) for z in z_fit])
    if len(z_fit) == 1:
        return targets, np.full(len(z_steps), float(r_fit[0]))
    return targets, np.asarray(np.interp(z_steps, z_fit, r_fit), dtype=float)


def aimed_force_n(probe: ProbeResult, task: SurfaceTaskSpec) -> float:
    """The contact force (N) at which the task's sensor will read the desired force.

    The desired force less the sensor's free-space reading at the probe's end
    (:meth:`ProbeResult.free_space_reading_n`: its bias drift since it was
    zeroed), which the task's readings carry; none when the task tares the
    sensor before each trial (``task.tare_each_trial``).
    """
    if task.tare_each_trial:
        return task.desired_force_n
    return task.desired_force_n - probe.free_space_reading_n()


def relaxation_share(probe: ProbeResult, least_force_n: float = 1.0) -> float:
    """Median share by which the probe's early readings passed its relaxed ones (0: none seen).

    Over the press readings above ``least_force_n`` (N): (early − relaxed) / relaxed.
    """
    shares = [
        (row["early_force_n"] - row["force_n"]) / row["force_n"]
        for row in probe.rows
        if row["phase"] == "press" and row["force_n"] > least_force_n
    ]
    return max(float(np.median(shares)), 0.0) if shares else 0.0


def warm_start(
    learner: SRVLearner, probe: ProbeResult, task: SurfaceTaskSpec, output: SurfaceYOutput
) -> None:
    """Set every box's μ and r̂ from the probe (module docstring); the learner's first output.

    A box holding several steps (``task.input_parts`` < steps) takes their mean;
    a box holding none keeps its start values.
    """
    targets, r_hats = step_targets(probe, task)
    step_mm = abs(task.z_step_mm)
    limit = output.max_offset_mm / output.scale_mm
    means: dict[tuple[int, ...], list[float]] = {}
    preds: dict[tuple[int, ...], list[float]] = {}
    others = [[d.low + (i + 0.5) * d.width for i in range(d.parts)]
              for d in learner.grid.dimensions[1:]]  # e.g. the last move's direction
    for k in range(task.steps_per_trial):
        offset = (float(targets[k]) - output.centre_of_step(k)) / output.scale_mm
        for rest in itertools.product(*others):
            box = learner.grid.index(np.array([k * step_mm, *rest]))
            means.setdefault(box, []).append(min(max(offset, -limit), limit))
            preds.setdefault(box, []).append(float(r_hats[k]))
    for box, values in means.items():
        learner.weights[box] = float(np.mean(values))
        learner.predictions[box] = float(np.mean(preds[box]))
