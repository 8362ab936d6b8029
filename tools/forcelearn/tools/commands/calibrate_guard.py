"""The guarded steps of ``forcelearn calibrate``: the sensor's range checked before every turn.

On top of :class:`~forcelearn.tools.experiments.calibration_run.Calibrator`
(free space, bias and noise, per-pose settling and averaging),
:class:`GuardedCalibrator` adds:

* **Probes.** Right after the zero, three turns of ``PROBE_DEG`` (10 deg) of the
  first orientation about world +x, +y and -x: with the first pose, four
  gravity directions that are not coplanar, which determine the reading at
  any orientation (:class:`~forcelearn.calibration.predict.ReadingModel`). A
  10 deg turn changes any reading by at most 17 % of the tool's weight and
  gravity moment: the probes are the only turns made without a prediction.
  They read a quarter of a pose's samples and feed the prediction only, not the fit.
* **The range before every turn.** From then on, every step of every turn
  (poses, added poses, the turn back) is predicted first; a step whose reading
  (value + 4 sigma) would pass 0.9 of the full scale on any axis is not made:
  :class:`~forcelearn.errors.PoseOutOfRange`. With the default plan the pose is
  skipped and said so; with the operator's ``--poses`` the calibration stops.
* **Poses added where needed.** With the default plan, when skipped poses
  leave the fit's condition number above the limit, the candidate orientation
  (tool down, horizontal, 45 deg) that lowers it most and is in range is added,
  until the set passes (at most ``MAX_ADDED``).
* **The force limit on contact, not weight.** Once the reading is predicted,
  the cell's compensation subtracts it: the force limit read between turn
  steps sees what differs from free space (a touch), not the tool's weight
  turning (a 10 kg tool changes its reading by 98 N over 60 deg).
* **A still tool.** The first and second halves of a pose's samples must agree
  within ``MOVED_SIGMAS`` standard errors (estimated from blocks of the read
  itself, so the adapter filter's correlation is counted): else the tool moved
  during the read (loose, swinging, a cable pulling) and the pose is refused.
* **The bias drift.** The first orientation is measured again at the end
  (instead of only turning back to it): what changed there is the sensor's
  bias drift, and the fit takes the bias as linear in time (6 more
  parameters, :func:`~forcelearn.calibration.fit.drift_times`).
* **Passes until precise.** With revisits, the fit is generalised least
  squares with the bias a random walk about its piecewise-linear fit; while
  the centre of mass's σ exceeds a third of 1 mm + 0.5 % of its distance, the
  pass is measured again as often as the design predicts it takes (at most
  ``max_passes``; turns of up to ``repeat_rotation_step_deg`` per step), and
  the σ reached and the cell time are printed
  (:mod:`~forcelearn.tools.commands.calibrate_precision`).
* **The mounting.** The fit takes the sensor's mounting on the flange as given
  (``--mounting-rpy-deg``/``--mounting-quaternion``, or ``[calibration]
  mounting_*`` of the config) or estimates it with the tool
  (:mod:`forcelearn.calibration.mounting`).
"""

from __future__ import annotations

import logging
import math
from dataclasses import replace
from typing import Any, TextIO

import numpy as np

from forcelearn.calibration import AXES, MAX_CONDITION, check_pose_set, condition_number
from forcelearn.calibration.fit import CANDIDATES, bias_knots, orientation_with_down
from forcelearn.calibration.model import Quaternion, ToolLoad
from forcelearn.calibration.mounting import fit_with_mounting
from forcelearn.calibration.predict import ReadingModel, out_of_range
from forcelearn.devices import Pose, multiply_quaternions
from forcelearn.errors import CalibrationError, PoseOutOfRange
from forcelearn.site.session import CellSession
from forcelearn.tools.commands.calibrate_precision import (
    Measured,
    com_sigma_mm,
    drift_model,
    mean_variance,
    passes_needed,
    target_mm,
)
from forcelearn.tools.experiments.calibration_plan import CalibrationPlan, NamedPose, slerp_steps
from forcelearn.tools.experiments.calibration_run import Ask, Calibrator, Measurement

log = logging.getLogger(__name__)

PROBE_DEG = 10.0
"""Turn of each probe from the first orientation, deg."""
PROBE_AXES = (("+x", (1.0, 0.0, 0.0)), ("+y", (0.0, 1.0, 0.0)), ("-x", (-1.0, 0.0, 0.0)))
PROBE_MIN_SAMPLES = 50
"""Fewest samples averaged at a probe."""
MAX_ADDED = 6
"""Most orientations added to a default plan whose skipped poses left it ill-conditioned."""
MOVED_SIGMAS = 6.0
"""Half-means further apart than this many standard errors: the tool moved during the read."""
BLOCKS = 10
"""Blocks a pose's read is cut into to estimate the standard error of its half-means."""


def turned(q: Quaternion, axis_world: tuple[float, float, float], angle_deg: float) -> Quaternion:
    """Return ``q`` turned by ``angle_deg`` about a world axis (through the tool point)."""
    axis = np.asarray(axis_world, dtype=float) / np.linalg.norm(axis_world)
    half = math.radians(angle_deg) / 2
    turn = (math.cos(half), *(float(c) * math.sin(half) for c in axis))
    w, x, y, z = multiply_quaternions(turn, q)
    norm = math.sqrt(w * w + x * x + y * y + z * z)
    return (w / norm, x / norm, y / norm, z / norm)


def check_still(samples: list[Any], std: np.ndarray) -> None:
    """Refuse a read whose first and second halves differ beyond MOVED_SIGMAS standard errors."""
    w = np.array([s.wrench for s in samples], dtype=float)
    if len(w) < 2 * BLOCKS:
        return
    blocks = np.array([b.mean(axis=0) for b in np.array_split(w, BLOCKS)])
    half = BLOCKS // 2
    first, second = blocks[:half], blocks[half:]
    within = np.sqrt((first.var(axis=0, ddof=1) + second.var(axis=0, ddof=1)) / 2)
    floor = np.asarray(std, dtype=float) / math.sqrt(len(w) / BLOCKS)  # independent samples
    error = np.maximum(within, floor) * math.sqrt(1 / half + 1 / (BLOCKS - half))
    jump = np.abs(first.mean(axis=0) - second.mean(axis=0))
    if np.any(jump > MOVED_SIGMAS * error):
        worst = int(np.argmax(jump / error))
        raise CalibrationError(
            f"the tool moved during the read: {AXES[worst]} changed by {jump[worst]:.3g} between "
            f"the first and second half of the samples, {jump[worst] / error[worst]:.1f} standard "
            f"errors (limit {MOVED_SIGMAS:g}); tighten the tool, clear its cable and run again"
        )


class _KeepLast:
    """The sensor driver, keeping the last batch of ``count`` samples read (for check_still)."""

    def __init__(self, sensor: Any, count: int) -> None:
        self._sensor, self.count = sensor, count
        self.last: list[Any] = []

    def read_many(self, count: int, *args: Any) -> list[Any]:
        samples: list[Any] = self._sensor.read_many(count, *args)
        if count == self.count:
            self.last = samples
        return samples

    def __getattr__(self, name: str) -> Any:
        return getattr(self._sensor, name)


class GuardedCalibrator(Calibrator):
    """The calibration steps with the range predicted before each turn (module docstring).

    Args:
        full_scales: the sensor's full scales (N, N*m); zeros: unknown, no range check.
        mounting: the sensor's mounting on the flange (w, x, y, z), or None to estimate it.
        complete: skip out-of-range poses and add orientations where needed (default plan).
        others: as :class:`Calibrator`.
    """

    def __init__(self, session: CellSession, plan: CalibrationPlan, *,
                 full_scales: tuple[float, ...], mounting: Quaternion | None = None,
                 complete: bool = False, manual: bool = False, ask: Ask = input,
                 progress: bool = True, out: TextIO | None = None) -> None:
        super().__init__(session, plan, manual=manual, ask=ask, progress=progress, out=out)
        self.sensor = _KeepLast(self.sensor, plan.samples_per_pose)
        self.full_scales = np.asarray(full_scales, dtype=float)
        if not np.all(self.full_scales > 0):
            log.warning("the sensor's full scales are unknown: the range is not checked")
        self.mounting, self.complete = mounting, complete
        self.model: ReadingModel | None = None
        self.skipped: list[str] = []
        """Poses not measured: out of the sensor's range (default plan only)."""
        self.added: list[str] = []
        """Orientations added to keep the fit well-conditioned."""
        self._commanded: dict[str, Quaternion] = {}
        self.start_s = math.nan
        """The controller's time (s) at the zero."""
        self.duration_s = math.nan
        """Cell time (s) from the zero to the last pose read (with revisits)."""

    def run(self) -> Measurement:
        """Measure bias, noise and tool load; raises CalibrationError on any failure."""
        before = self.cell.compensation
        try:
            return self._run()
        finally:
            self.cell.compensation = before

    def _run(self) -> Measurement:
        plan, poses = self.plan, list(self.plan.poses)
        if not self.manual:  # refuse a bad set before the robot moves at all
            check_pose_set([p.quaternion for p in poses], plan.max_condition)
        with self._step("moving to the free-space position"):
            self._go_to_start()
        with self._step("bias and noise"):
            noise = self._bias_and_noise()
        self.start_s = self.in_position_s
        self.model = ReadingModel(np.maximum(noise.std, 1e-6))
        again = NamedPose(f"{poses[0].name}, again (bias drift)", poses[0].quaternion)
        queue = [(f"pose {i}/{len(poses)}", p) for i, p in enumerate(poses, start=1)]
        every = 0 if self.manual else plan.revisit_every  # the operator jogs few poses
        if every > 0:  # the first orientation again after every ``every`` poses, not the last
            queue = queue[:1] + [entry for k, pose in enumerate(queue[1:], start=1) for entry in
                                 ([pose, ("revisit", again)]
                                  if k % every == 0 and k < len(queue) - 1 else [pose])]
        if not self.manual:
            first = poses[0].quaternion
            probes = [(f"probe {i}/{len(PROBE_AXES)}",
                       NamedPose(f"probe {PROBE_DEG:g} deg about world {name}",
                                 turned(first, axis, PROBE_DEG)))
                      for i, (name, axis) in enumerate(PROBE_AXES, start=1)]
            queue = queue[:1] + probes + queue[1:]
        measured: list[Measured] = []
        for label, pose in queue:
            if label.startswith("probe"):  # for the prediction only: a quarter of the samples
                self._probe(label, pose)
            elif label != "revisit" or self._first_measured(measured, poses[0]):
                self._measure(label, pose, measured)
        if self.complete and not self.manual:
            self._add_where_needed(measured)
        if every > 0 and self._first_measured(measured, poses[0]):
            self._measure("revisit", again, measured)  # also turns back to the first
            tool = self._fit(measured, noise.std)
            tool = self._until_precise(measured, noise.std, tool)
        else:
            if not self.manual:
                with self._step("turning back to the first orientation"):
                    self._turn_to(poses[0].quaternion)
            tool = self._fit(measured, noise.std)
        return Measurement(noise, tool)

    def _fit(self, measured: list[Measured], std: np.ndarray) -> ToolLoad:
        """The tool-load fit of the poses so far (GLS when the first pose was revisited)."""
        times = np.array([m[4] for m in measured])
        revisited = bias_knots([m[1] for m in measured], times, self.plan.max_condition)
        return fit_with_mounting(
            [m[1] for m in measured], np.array([m[2] for m in measured]).reshape(-1, 6),
            axis_std=np.maximum(std, 1e-6), names=[m[0] for m in measured],
            samples=[m[3] for m in measured], limit=self.plan.max_condition,
            mounting=self.mounting, times_s=times,
            drift=drift_model(measured) if revisited is not None else None)

    def _until_precise(self, measured: list[Measured], std: np.ndarray,
                       tool: ToolLoad) -> ToolLoad:
        """Repeat the pass until the centre of mass's sigma meets its target.

        How many passes: :mod:`.calibrate_precision`; prints what was achieved and the
        cell time taken.
        """
        cycle, passes = list(measured), 1
        while com_sigma_mm(tool) > target_mm(tool) and passes < self.plan.max_passes:
            more = passes_needed(measured, cycle, tool, self.plan.max_passes - passes,
                                 self.plan.max_condition)
            print(f"centre of mass sigma {com_sigma_mm(tool):.2f} mm > target "
                  f"{target_mm(tool):.2f} mm: {more} more pass(es) of the orientations",
                  file=self.out)
            first_pass = self.plan  # the path is known: turn in the repeat passes' steps
            self.plan = replace(first_pass, max_rotation_step_deg=max(
                first_pass.max_rotation_step_deg, first_pass.repeat_rotation_step_deg))
            try:
                for _ in range(more):
                    passes += 1
                    for m in cycle[1:]:
                        self._measure(f"pass {passes}", NamedPose(
                            f"{m[0]}, pass {passes}", self._commanded[m[0]]), measured)
            finally:
                self.plan = first_pass
            tool = self._fit(measured, std)
        met = "met" if com_sigma_mm(tool) <= target_mm(tool) else "NOT met"
        self.duration_s = measured[-1][4] - self.start_s
        print(f"precision: centre of mass sigma {com_sigma_mm(tool):.2f} mm (RMS of the error's "
              f"norm), target {target_mm(tool):.2f} mm (a third of 1 mm + 0.5 % of "
              f"|c|) {met}; {passes} pass(es), {len(measured)} poses, "
              f"{self.duration_s:.0f} s of cell time from the zero", file=self.out)
        return tool

    @staticmethod
    def _first_measured(measured: list[Measured], first: NamedPose) -> bool:
        """Whether the plan's first orientation was measured (the bias drift's reference)."""
        return bool(measured) and measured[0][0] == first.name

    # ---- one pose, guarded ------------------------------------------------------------
    def _measure(self, label: str, pose: NamedPose,
                 measured: list[Measured]) -> bool:
        """Measure one pose into ``measured``; False when skipped (out of range, or operator)."""
        problems = self._path_problems(pose.quaternion)
        if problems:
            message = (f"{label} ({pose.name}) would pass the sensor's range: "
                       f"{'; '.join(problems)}; the robot was not moved there")
            if not self.complete:
                raise PoseOutOfRange(f"{message}: use smaller tilts (--poses), a lighter tool or "
                                     "a sensor of larger range")
            print(f"skipped {message}", file=self.out)
            self.skipped.append(pose.name)
            return False
        with self._step(f"{label} ({pose.name})"):
            result = self._measure_pose(len(measured) + 1, pose, np.asarray(
                self.model.noise_std if self.model is not None else 1.0))
            if result is None:
                return False
            std = np.asarray(self.model.noise_std if self.model is not None else 0.0)
            check_still(self.sensor.last, std)
            variance = mean_variance(self.sensor.last, std)
            # the pose's time on the controller's clock (the cell's one clock when emulated;
            # the samples' own stamps are the host's): midway from in position to read done
            read_s = (self.in_position_s + self.robot.wait_in_position(
                self.plan.settle_timeout_s, 0.0)) / 2
        reached, mean, count = result
        measured.append((pose.name, reached, mean, count, read_s, variance))
        self._commanded.setdefault(pose.name, pose.quaternion)
        if self.model is not None:
            self.model.add(reached, mean, count)
            if self.model.determined:  # the force limit now watches for contact, not weight
                self.cell.compensation = self._expected_free_space
        return True

    def _expected_free_space(self, wrench: np.ndarray, pose: Pose) -> np.ndarray:
        """The reading less what free space is predicted to read at ``pose`` (Cell hook)."""
        assert self.model is not None
        predicted, _ = self.model.predict(pose.quaternion)
        expected: np.ndarray = np.asarray(wrench, dtype=float) - predicted
        return expected

    def _probe(self, label: str, pose: NamedPose) -> None:
        """Measure a probe with a quarter of the samples; it feeds the prediction, not the fit."""
        full = self.plan
        self.plan = replace(full, samples_per_pose=max(PROBE_MIN_SAMPLES,
                                                       full.samples_per_pose // 4))
        self.sensor.count = self.plan.samples_per_pose
        try:
            self._measure(label, pose, [])
        finally:
            self.plan, self.sensor.count = full, full.samples_per_pose

    def _path_problems(self, target: Quaternion) -> list[str]:
        """What passes the range on the way to ``target`` (every step; the target in manual)."""
        if self.model is None or not self.model.determined or not np.all(self.full_scales > 0):
            return []
        steps = [target] if self.manual else slerp_steps(
            self._orientation, target, self.plan.max_rotation_step_deg)
        for q in steps:
            problems = out_of_range(self.model, q, self.full_scales)
            if problems:
                return problems
        return []

    def _turn_to(self, quaternion: Quaternion) -> None:
        problems = self._path_problems(quaternion)
        if problems:
            raise PoseOutOfRange(f"the turn would pass the sensor's range: {'; '.join(problems)}")
        super()._turn_to(quaternion)

    def _add_where_needed(self, measured: list[Measured]) -> None:
        """Add candidate orientations in range until the condition number passes."""
        tried: set[str] = set()
        limit = self.plan.max_condition if self.plan.max_condition else MAX_CONDITION
        while condition_number([m[1] for m in measured]) > limit and len(self.added) < MAX_ADDED:
            options = [(name, orientation_with_down(np.array(axis))) for name, axis in CANDIDATES
                       if name not in tried and not self._path_problems(
                           orientation_with_down(np.array(axis)))]
            if not options:
                break
            name, q = min(options, key=lambda o: condition_number([*(m[1] for m in measured),
                                                                   o[1]]))
            tried.add(name)
            if self._measure(f"added {len(self.added) + 1}", NamedPose(f"added: {name}", q),
                             measured):
                self.added.append(name)
