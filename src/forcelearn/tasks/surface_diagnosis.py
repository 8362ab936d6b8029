"""Say when the §5 learning is stuck, and why, while the run goes on and at its end.

Two signs, checked after every trial (:class:`StuckMonitor`):

* **at the edge**: in ``edge_trials`` trials in a row, at least ``edge_share``
  of the steps commanded a Y within ``edge_band`` of the output range's end
  (``centre ± max_offset``). The learner wants a Y the range does not hold:
  the desired force lies outside it (a softer or harder sponge, another
  force, wear). The advice fits where the map came from (``source``): the
  probe's range (its ``[probe]`` keys), configured keys (remove them so the
  probe chooses), or the fallback without a probe;
* **no trial completes**: none of the last ``stall_trials`` trials ran all its
  steps. Keys: ``task.tolerance_n`` (the failure band), the output map.

The monitor warns once per sign (the caller prints it); :func:`diagnose`
gives the run's end verdict for summary.json: ``converged`` (the criterion was
met once), ``in_band_at_end`` (the run *ended* in band: its last
``CONVERGENCE_WINDOW`` trials all complete, their median force RMS within 5 %
of the desired force), ``trials_out_of_band_after_convergence`` and a
``diagnosis`` whenever the run did not end in band (converged or not).

The diagnosis names the physical cause the records show (:func:`physical_causes`,
from the last trials' steps and the probe, :class:`RunEvidence`), with its figures:

* **hysteresis**: the force error of steps that pressed in and of steps that eased
  off differ by more than the noise (a regression on the step's offset from its
  mean Y and the move's direction: the elastic part apart), both branch means given;
* **a tolerance below what the surface fit resolves**: band / k (the position band)
  under the probe's standard error of the target Y;
* **infeasible force**: :mod:`forcelearn.tasks.surface_feasibility`'s verdict;
* **noise against the band**: the steps' force scatter the regression leaves is at
  least the band;

and says "more trials may do" only where the learning curve still falls (the last
trials' force RMS against trial has a slope below zero by ``FALLING_SIGMAS``
standard errors); a flat curve is said to be flat.
"""

from __future__ import annotations

import math
import statistics
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from forcelearn.tasks.surface_feasibility import Feasibility
from forcelearn.tasks.surface_fit import ProbeResult
from forcelearn.tasks.surface_map import step_centre_y_mm
from forcelearn.trainer import CONVERGENCE_TOLERANCE, CONVERGENCE_WINDOW, TrialRecord

MAP_SOURCES = ("probe", "config", "probe+config", "fallback")


@dataclass
class StuckMonitor:
    """Watches the Y commands and completions of each trial; returns a warning once per sign.

    Args:
        centre_y_mm, max_offset_mm: the output map's centre and half-range (mm).
        steps_per_trial: steps of a complete trial.
        path_y_mm: a map that follows the surface: the centre of each step (mm).
        source: where the map came from (:data:`MAP_SOURCES`): the advice fits it.
    """

    centre_y_mm: float
    max_offset_mm: float
    steps_per_trial: int
    path_y_mm: tuple[float, ...] = ()
    source: str = "probe"
    edge_trials: int = 20
    """Trials in a row at the edge before the warning."""
    edge_share: float = 0.5
    """Share of a trial's steps at the edge that counts the trial as at the edge."""
    edge_band: float = 0.02
    """Within this share of max_offset of the end counts as at the edge."""
    stall_trials: int = 50
    """Trials in a row without one complete before the warning."""
    edge_run: int = 0
    stall_run: int = 0
    edge_side: str = ""
    shift_mm: float = 0.0
    """The map's wear shift at the latest trial (mm)."""
    warnings: list[str] = field(default_factory=list)
    _warned: set[str] = field(default_factory=set)

    def update(
        self, record: TrialRecord, commands_y_mm: Sequence[float], shift_mm: float = 0.0
    ) -> str | None:
        """Account one trial; return a new warning (once per sign) or None.

        ``shift_mm`` is the map's wear shift during the trial (mm; see
        :attr:`~forcelearn.tasks.surface.SurfaceYOutput.shift_mm`): the range's
        ends moved with it.
        """
        self.shift_mm = shift_mm
        limit = self.max_offset_mm * (1.0 - self.edge_band)
        offsets = [
            y - step_centre_y_mm(self.path_y_mm, self.centre_y_mm, k) - shift_mm
            for k, y in enumerate(commands_y_mm)
        ]
        low = sum(1 for d in offsets if d <= -limit)
        high = sum(1 for d in offsets if d >= limit)
        count = max(len(commands_y_mm), 1)
        if max(low, high) / count >= self.edge_share:
            self.edge_run += 1
            self.edge_side = "deep" if low >= high else "shallow"
        else:
            self.edge_run = 0
        complete = (not record.failed) and record.steps == self.steps_per_trial
        self.stall_run = 0 if complete else self.stall_run + 1
        if self.edge_run >= self.edge_trials and "edge" not in self._warned:
            return self._warn("edge", self.edge_text(record.index))
        if self.stall_run >= self.stall_trials and "stall" not in self._warned:
            return self._warn("stall", self.stall_text(record.index))
        return None

    def edge_text(self, index: int) -> str:
        """The 'at the edge' warning; its advice fits the map's source."""
        deep = self.edge_side == "deep"
        centre = self.centre_y_mm + self.shift_mm
        end = centre + (-1 if deep else 1) * self.max_offset_mm
        reach = "more force" if deep else "less force"
        shifted = f" after a wear shift of {self.shift_mm:+.1f} mm" if self.shift_mm else ""
        advice = {
            "probe": (
                "the surface probe chose this range ([probe]): the force may be beyond what "
                "probe.max_depth_mm allows after wear (see the feasibility in summary.json), "
                "else widen it with probe.wear_margin, or set task.max_offset_mm"
            ),
            "config": (
                "widen task.max_offset_mm (and task.output_scale_mm), or remove "
                "task.output_centre_y_mm, task.output_scale_mm and task.max_offset_mm from "
                "[task] so the surface probe chooses the map"
            ),
            "probe+config": (
                "the keys you set in [task] (task.output_centre_y_mm, task.output_scale_mm, "
                "task.max_offset_mm) override the probe's choice: remove them so the probe "
                "chooses, or widen task.max_offset_mm"
            ),
            "fallback": (
                "no probe chose this range (start Y, 2 mm, 15 mm): enable the surface probe "
                "([probe] enabled = true) or configure task.output_centre_y_mm and "
                "task.max_offset_mm"
            ),
        }.get(self.source, "widen the output range")
        return (
            f"learning is stuck: for {self.edge_run} trials in a row (to trial {index}) most "
            f"Y commands sat at the {self.edge_side} end of the output range (y = {end:.1f} mm "
            f"= centre {centre:.1f} mm {'-' if deep else '+'} {self.max_offset_mm:.1f} mm"
            f"{shifted}); the desired force likely needs {reach} than the range can give: "
            f"{advice}"
        )

    def stall_text(self, index: int) -> str:
        """The 'no trial completes' warning."""
        return (
            f"learning is stuck: no trial completed in the last {self.stall_run} (to trial "
            f"{index}); every one failed its force band: check task.desired_force_n against "
            "the sponge, task.tolerance_n, and the output map (task.output_centre_y_mm, "
            "task.max_offset_mm, task.output_scale_mm, or let the probe choose them)"
        )

    def _warn(self, sign: str, text: str) -> str:
        self._warned.add(sign)
        self.warnings.append(text)
        return text


BRANCH_SIGMAS = 3.0
"""A branch gap counts as hysteresis when it passes this many standard errors."""
FALLING_SIGMAS = 2.0
"""The learning curve still falls when its slope is this many standard errors below 0."""
CURVE_TRIALS = 30
"""Trials at the end whose force RMS the learning-curve slope is fitted to."""
MOVE_MIN_MM = 0.05
"""A step whose Y moved less than this (mm) counts neither as pressing in nor easing off."""


@dataclass(frozen=True)
class RunEvidence:
    """What the records hold for the physical causes (forces N, lengths mm)."""

    desired_force_n: float
    commands_y_mm: Sequence[Sequence[float]]
    """The Y command of every step of the last trials (one sequence per trial)."""
    forces_n: Sequence[Sequence[float]]
    """The force read at every step of the same trials."""
    force_rms_n: Sequence[float]
    """Every trial's force RMS (the learning curve)."""
    probe: ProbeResult | None = None
    approach_mm: float = 0.0
    """The task's approach from the loading side (0: direct moves)."""

    @property
    def band_n(self) -> float:
        """The convergence band, 5 % of the desired force, N."""
        return CONVERGENCE_TOLERANCE * abs(self.desired_force_n)


@dataclass(frozen=True)
class BranchSplit:
    """The step force errors split by the move's direction, the elastic part apart (N)."""

    pressing_mean_n: float
    """Mean force of the steps that pressed in, at their mean Y."""
    easing_mean_n: float
    """Mean force of the steps that eased off, at their mean Y."""
    gap_std_n: float
    """Standard error of pressing − easing."""
    scatter_n: float
    """The scatter of a step's force the split leaves (noise and all else), N."""
    steps: int


def branch_split(evidence: RunEvidence) -> BranchSplit | None:
    """Regress each step's force on its offset from its step's mean Y and its move's direction.

    force = F̄ + b · (y − ȳ_k) + g · direction (+1 pressing in, −1 easing off); the
    branch means are F̄ ± g. None: too few moves either way.
    """
    commands = [np.asarray(c, float) for c in evidence.commands_y_mm]
    forces = [np.asarray(f, float) for f in evidence.forces_n]
    steps = min((len(c) for c in commands), default=0)
    if steps < 3 or len(commands) < 2:
        return None
    y = np.array([c[:steps] for c in commands])
    f = np.array([ff[:steps] for ff in forces])
    moved = y[:, 1:] - y[:, :-1]
    direction = np.where(moved < -MOVE_MIN_MM, 1.0, np.where(moved > MOVE_MIN_MM, -1.0, 0.0))
    offset = (y - y.mean(axis=0))[:, 1:]
    force = f[:, 1:]
    keep = (direction != 0) & np.isfinite(force)
    if min(int(np.sum(direction[keep] > 0)), int(np.sum(direction[keep] < 0))) < 3:
        return None
    design = np.column_stack([np.ones(int(keep.sum())), offset[keep], direction[keep]])
    coef, *_ = np.linalg.lstsq(design, force[keep], rcond=None)
    residual = force[keep] - design @ coef
    dof = max(len(residual) - 3, 1)
    s2 = float(residual @ residual) / dof
    cov = s2 * np.linalg.pinv(design.T @ design)
    mean_n, gap = float(coef[0]), float(coef[2])
    return BranchSplit(mean_n + gap, mean_n - gap, 2.0 * math.sqrt(max(float(cov[2, 2]), 0.0)),
                       math.sqrt(s2), len(residual))


def curve_slope(force_rms_n: Sequence[float], trials: int = CURVE_TRIALS) -> tuple[float, float]:
    """Slope of the last ``trials`` trials' force RMS against trial, and its standard error."""
    rms = np.asarray(force_rms_n[-trials:], float)
    if len(rms) < 5:
        return math.nan, math.nan
    x = np.arange(len(rms), dtype=float)
    design = np.column_stack([np.ones_like(x), x])
    coef, *_ = np.linalg.lstsq(design, rms, rcond=None)
    residual = rms - design @ coef
    s2 = float(residual @ residual) / (len(rms) - 2)
    return float(coef[1]), math.sqrt(s2 / float(np.sum((x - x.mean()) ** 2)))


def still_falling(force_rms_n: Sequence[float]) -> bool:
    """True when the learning curve's last trials still fall (module docstring)."""
    slope, std = curve_slope(force_rms_n)
    return math.isfinite(slope) and slope < -FALLING_SIGMAS * std


def physical_causes(evidence: RunEvidence) -> list[str]:
    """The physical causes the records show, each with its figures (module docstring)."""
    causes = []
    band = evidence.band_n
    split = branch_split(evidence)
    if split is not None:
        gap = split.pressing_mean_n - split.easing_mean_n
        if abs(gap) > BRANCH_SIGMAS * split.gap_std_n and abs(gap) > 0.5 * band:
            fitted = ""
            if evidence.probe is not None:
                fitted = f"; the probe: {evidence.probe.hysteresis().describe()}"
            advice = ('approach each step from the loading side (task.approach = "loading")'
                      if evidence.approach_mm == 0 else
                      "the approach from the loading side is too short for this foam's "
                      "branch depth: check the probe's ease_off_mm")
            causes.append(
                f"hysteresis: steps that pressed in read {split.pressing_mean_n:.2f} N, steps "
                f"that eased off {split.easing_mean_n:.2f} N at the same Y (difference "
                f"{gap:+.2f} ± {split.gap_std_n:.2f} N over {split.steps} steps, against the "
                f"{band:.2f} N band){fitted}: {advice}")
    probe = evidence.probe
    if probe is not None and probe.fits:
        k = probe.stiffness_n_per_mm()
        sigma_y = max(math.hypot(f.contact_y_std,
                                 evidence.desired_force_n / f.stiffness_n_per_mm**2
                                 * f.stiffness_std) for f in probe.fits)
        position_band = band / k
        if position_band < sigma_y:
            causes.append(
                f"the tolerance is below what the surface fit resolves: the {band:.2f} N band "
                f"is ±{position_band:.3f} mm of position at {k:.2f} N/mm, the probe places the "
                f"target Y to ±{sigma_y:.3f} mm (its largest standard error): more probe "
                "samples ([probe] samples) or press points, or a wider band")
    if split is not None and split.scatter_n >= band and not causes:  # hysteresis scatters too
        causes.append(
            f"noise against the band: the steps' force scatters by {split.scatter_n:.2f} N "
            f"(what their Y and move direction do not explain) against the {band:.2f} N band: "
            "more samples per step ([task] measurement_window_s) or a quieter sensor")
    return causes


def in_band(record: TrialRecord, steps_per_trial: int, band_n: float) -> bool:
    """True for a complete trial (no failure, every step) within ``band_n`` force RMS."""
    return (not record.failed) and record.steps == steps_per_trial and record.force_rms_n <= band_n


def diagnose(
    records: Sequence[TrialRecord],
    converged_at: int | None,
    monitor: StuckMonitor,
    desired_force_n: float,
    feasibility: Feasibility | None = None,
    window: int = CONVERGENCE_WINDOW,
    evidence: RunEvidence | None = None,
) -> dict[str, Any]:
    """The end verdict for summary.json (module docstring).

    Returns ``converged``, ``in_band_at_end``, ``trials_out_of_band_after_convergence``
    and ``diagnosis`` (None only for a run that converged and ended in band).
    The diagnosis names the physical reason when the run found one
    (``feasibility``, then :func:`physical_causes` of ``evidence``), else the stuck
    monitor's sign, else the figures; "more trials may do" only where the learning
    curve still falls.
    """
    steps, band = monitor.steps_per_trial, CONVERGENCE_TOLERANCE * abs(desired_force_n)
    tail = list(records[-window:])
    end_ok = (
        len(tail) == window
        and all((not r.failed) and r.steps == steps for r in tail)
        and statistics.median(r.force_rms_n for r in tail) <= band
    )
    after = None
    if converged_at is not None:
        after = sum(
            not in_band(r, steps, band) for r in records if r.index >= converged_at + window
        )
    verdict: dict[str, Any] = {
        "converged": converged_at is not None,
        "in_band_at_end": end_ok,
        "trials_out_of_band_after_convergence": after,
        "diagnosis": None,
    }
    if converged_at is not None and end_ok:
        return verdict
    if not records:
        verdict["diagnosis"] = "no trial ran"
        return verdict
    last = records[-1].index
    causes = physical_causes(evidence) if evidence is not None else []
    if feasibility is not None:
        reason = "; ".join([feasibility.text(), *causes])
    elif causes:
        reason = "; ".join(causes)
    elif monitor.edge_run >= monitor.edge_trials:
        reason = monitor.edge_text(last)
    elif monitor.stall_run >= monitor.stall_trials:
        reason = monitor.stall_text(last)
    elif monitor.warnings:
        reason = monitor.warnings[-1]
    else:
        reason = ""
    failures = sum(r.failed for r in records)
    if converged_at is None:
        head = (
            f"not converged in {len(records)} trials ({failures} failed): no {window} complete "
            "trials in a row within 5 % force RMS of task.desired_force_n"
        )
        curve = [r.force_rms_n for r in records]
        if reason:
            tail_advice = ""
        elif evidence is None or still_falling(curve):
            tail_advice = "; more trials (run.trials / --trials) may do"
        else:
            slope, std = curve_slope(curve)
            tail_advice = (
                f"; the learning curve is flat over its last {min(len(curve), CURVE_TRIALS)} "
                f"trials (slope {slope:+.3f} ± {std:.3f} N per trial): more trials alone will "
                "not do")
    else:
        rms = statistics.median(r.force_rms_n for r in tail) if tail else float("nan")
        out = sum(not in_band(r, steps, band) for r in tail)
        head = (
            f"converged at trial {converged_at} but did not end in band: the last {len(tail)} "
            f"trials' median force RMS is {rms:.2f} N against the 5 % band of {band:.2f} N "
            f"({out} of them out of band; {after} trials out of band after convergence)"
        )
        tail_advice = (
            "; no physical reason found by the run (the learner's search wanders: more "
            "trials, or a smaller learner.sigma_min)" if not reason else ""
        )
    verdict["diagnosis"] = f"{head}: {reason}" if reason else head + tail_advice
    return verdict
