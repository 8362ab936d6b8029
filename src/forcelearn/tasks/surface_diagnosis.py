"""Say when the §5 learning is stuck, and why, while the run goes on and at its end.

Two signs, checked after every trial (:class:`StuckMonitor`):

* **at the edge**: in ``edge_trials`` trials in a row, at least ``edge_share``
  of the steps commanded a Y within ``edge_band`` of the output range's end
  (``centre ± max_offset``). The learner wants a Y the range does not hold:
  the desired force lies outside it (a softer or harder sponge, another
  force). Key to change: ``task.max_offset_mm`` / ``task.output_scale_mm``, or
  remove them so the probe chooses;
* **no trial completes**: none of the last ``stall_trials`` trials ran all its
  steps. Keys: ``task.tolerance_n`` (the failure band), the output map.

The monitor warns once per sign (the caller prints it); :func:`diagnose`
gives the run's end verdict for summary.json (``converged``, ``diagnosis``).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

from forcelearn.tasks.surface import step_centre_y_mm
from forcelearn.trainer import TrialRecord


@dataclass
class StuckMonitor:
    """Watches the Y commands and completions of each trial; returns a warning once per sign.

    Args:
        centre_y_mm, max_offset_mm: the output map's centre and half-range (mm).
        steps_per_trial: steps of a complete trial.
        path_y_mm: a map that follows the surface: the centre of each step (mm).
    """

    centre_y_mm: float
    max_offset_mm: float
    steps_per_trial: int
    path_y_mm: tuple[float, ...] = ()
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
        """The 'at the edge' warning."""
        end = self.centre_y_mm + (-1 if self.edge_side == "deep" else 1) * self.max_offset_mm
        reach = "more force" if self.edge_side == "deep" else "less force"
        return (
            f"learning is stuck: for {self.edge_run} trials in a row (to trial {index}) most "
            f"Y commands sat at the {self.edge_side} end of the output range (y = {end:.1f} mm "
            f"= centre {self.centre_y_mm:.1f} mm {'-' if self.edge_side == 'deep' else '+'} "
            f"{self.max_offset_mm:.1f} mm); the desired force likely needs {reach} than the "
            "range can give: widen task.max_offset_mm (and task.output_scale_mm), or remove "
            "them from [task] so the surface probe chooses the map"
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


def diagnose(
    records: Sequence[TrialRecord], converged_at: int | None, monitor: StuckMonitor
) -> tuple[bool, str | None]:
    """The end verdict: (converged, diagnosis); the diagnosis is None for a converged run."""
    if converged_at is not None:
        return True, None
    if not records:
        return False, "no trial ran"
    if monitor.edge_run >= monitor.edge_trials:
        return False, monitor.edge_text(records[-1].index)
    if monitor.stall_run >= monitor.stall_trials:
        return False, monitor.stall_text(records[-1].index)
    if monitor.warnings:
        return False, monitor.warnings[-1]
    failures = sum(r.failed for r in records)
    return False, (
        f"not converged in {len(records)} trials ({failures} failed): no 10 complete trials "
        "in a row within 5 % force RMS of task.desired_force_n; more trials "
        "(run.trials / --trials) may do"
    )
