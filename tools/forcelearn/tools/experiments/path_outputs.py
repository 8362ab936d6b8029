"""The path run's outputs: trials.csv, passes.csv, steps.csv, probe.csv, summary.json, figures.

Written from a :class:`~forcelearn.tools.experiments.path_state.PathRun` when
the run ends (or stops), each file atomically (docs/path.md, "The run
directory"). A pass is **in band** when it completes and its force RMS is at
most 5 % of the desired force (the project's band,
``trainer.CONVERGENCE_TOLERANCE``); with ``on_contact_loss = "continue"`` the RMS
is over the points in contact (the points lost are counted apart). The run
**ends in band** when its last ``END_WINDOW`` passes are; the final force RMS is
their median. The **tangential force** of a step is what the sensor reads across
the force axis (friction dragging the tool along the part), from the burst's
mean wrench in ``records.mcap``.
"""

from __future__ import annotations

import math
import statistics
from pathlib import Path
from typing import Any

import numpy as np

from forcelearn.atomic import atomic_write_bytes
from forcelearn.filtering import ForceFilterConfig
from forcelearn.paths import TaughtPath
from forcelearn.press_guard import press_agreement_n
from forcelearn.records import TrialRecords
from forcelearn.run_output import _csv_bytes, write_summary, write_trials
from forcelearn.site import CellConfig
from forcelearn.tasks.path import PathGeometry, PathTask
from forcelearn.tasks.path_probe import PathProbe
from forcelearn.tasks.path_spec import PathTaskSpec
from forcelearn.tools.experiments.fault_recovery import fault_summary
from forcelearn.tools.experiments.path_state import PathRun
from forcelearn.trainer import CONVERGENCE_TOLERANCE, TrialLog, TrialRecord

END_WINDOW = 5
"""Last passes that must all be in band for the run to end in band; the final RMS's window."""


def write_outputs(run: PathRun, path: TaughtPath, cell_time_s: float,
                  figures: bool = True) -> dict[str, Any]:
    """Write the run directory from the run's passes so far; return the summary.

    ``figures``: also ``path_forces.png`` and ``path_3d.png``
    (:mod:`forcelearn.tools.figures.path`).
    """
    config, out, task, probe = run.config, run.out, run.task, run.probe
    spec = config.path_task
    assert spec is not None and task is not None and probe is not None
    records, logs = run.result.records, run.logs
    rows = pass_rows(records, logs, spec)
    summary = summary_of(config, spec, path, probe, task, rows, run.seed, run.wall_s,
                         cell_time_s)
    summary["moves_outside_workspace"] = outside_workspace(config, spec, path, logs)
    summary["faults"] = fault_summary(out)
    summary["safety_this_session"] = safety_counts(task)
    write_trials(out, records)
    write_table(out / "passes.csv", rows)
    write_table(out / "steps.csv", [{"pass": float(i), **row} for i, trial_log in enumerate(logs)
                                    for row in trial_log.rows])
    write_probe(out, probe)
    write_summary(out, summary)
    if figures and logs:
        from forcelearn.tools.figures.path import plot_forces, plot_path_3d

        plot_forces(logs, spec.desired_force_n, out / "path_forces.png")
        plot_path_3d(np.asarray(path.positions_mm), logs[-1], out / "path_3d.png")
    return summary


def safety_counts(task: PathTask) -> dict[str, Any]:
    """This session's first-contact checks and press-guard cuts (not checkpointed).

    ``worst_*_share``: the largest difference over its allowance (< 1 passed): |second -
    first| of a contact pressed twice; (last pass's - this pass's) of one compared.
    """
    twice = [abs(b - a) / press_agreement_n(a) for a, b in task.contact_checks]
    compared = [(a - b) / press_agreement_n(a) for a, b in task.contact_compared]
    guard = getattr(task.cell, "press_guard", None)
    return {"contacts_pressed_twice": len(twice),
            "worst_twice_share": max(twice) if twice else None,
            "contacts_compared": len(compared),
            "worst_compared_share": max(compared) if compared else None,
            "press_guard_cuts": None if guard is None else int(guard.cuts)}


def write_probe(out: Path, probe: PathProbe) -> None:
    """probe.csv: the probe pass's offset, force, target and r̂ at every point."""
    write_table(out / "probe.csv", [
        {"point": float(k), "offset_mm": o, "force_n": f, "target_mm": t, "r_hat": r}
        for k, (o, f, t, r) in enumerate(zip(probe.offsets_mm, probe.forces_n,
                                             probe.targets_mm, probe.r_hats, strict=True))])


def add_tangential(trial_log: TrialLog, records: TrialRecords,
                   config: ForceFilterConfig) -> None:
    """Each step's ``tangential_force_n``: the burst's mean force across the force axis, N.

    The force axis in the sensor frame is the filter's (``direction``, or its axis); a
    step without a burst (a force-limit stop) gets NaN.
    """
    along = (np.asarray(config.direction) if config.direction is not None
             else np.eye(3)[config.axis] if config.axis < 3 else None)
    last: dict[int, Any] = {}
    for step in records.steps:
        if step.stage == "step" and step.burst is not None and step.burst.wrench_mean:
            last[step.index] = step.burst.wrench_mean
    for row in trial_log.rows:
        wrench = last.get(int(row["step"]))
        if wrench is None or along is None:
            row["tangential_force_n"] = math.nan
            continue
        force = np.asarray(wrench[:3], dtype=float)
        row["tangential_force_n"] = float(np.linalg.norm(force - (force @ along) * along))


def outside_workspace(config: CellConfig, spec: PathTaskSpec, path: TaughtPath,
                      logs: list[TrialLog]) -> int:
    """Steps whose commanded pose lay outside ``[safety]``'s workspace.

    The driver refuses them before sending, so a run that ends has none; counted from
    the log, not assumed.
    """
    points = PathGeometry(path, spec.force_axis)
    low, high = config.safety.workspace_min_mm, config.safety.workspace_max_mm
    count = 0
    for trial_log in logs:
        for row in trial_log.rows:
            pose = points.pose(int(row["point"]), row["offset_mm"])
            where = np.array([pose.x_mm, pose.y_mm, pose.z_mm])
            count += int(np.any(where < low) or np.any(where > high))
    return count


def write_table(path: Path, rows: list[dict[str, float]]) -> None:
    """A CSV of dict rows (the first row's keys as the header), written atomically."""
    header = list(rows[0]) if rows else ["pass"]
    atomic_write_bytes(path, _csv_bytes(header, [[row.get(h, "") for h in header]
                                                  for row in rows]))


def pass_rows(records: list[TrialRecord], logs: list[TrialLog],
              spec: PathTaskSpec) -> list[dict[str, float]]:
    """The path task's figures of each pass (passes.csv)."""
    band = CONVERGENCE_TOLERANCE * spec.desired_force_n
    rows = []
    for record, trial_log in zip(records, logs, strict=True):
        errors = np.array([row["force_error_n"] for row in trial_log.rows])
        lost = np.array([row.get("contact_lost", 0.0) for row in trial_log.rows]) > 0
        counted = errors[~lost] if spec.on_contact_loss == "continue" else errors
        rms = float(np.sqrt(np.mean(counted**2))) if counted.size else math.nan
        complete = (not record.failed) and record.steps == len(trial_log.rows) and \
            len(trial_log.rows) > 0
        offsets = [abs(row["offset_mm"]) for row in trial_log.rows]
        across = [row.get("tangential_force_n", math.nan) for row in trial_log.rows]
        known = [v for v in across if math.isfinite(v)]
        rows.append({
            "pass": float(record.index), "complete": float(complete),
            "force_rms_n": rms, "force_rms_all_n": record.force_rms_n,
            "max_abs_error_n": float(np.max(np.abs(counted))) if counted.size else math.nan,
            "contact_lost": float(lost.sum()), "start_force_n": record.start_force_n,
            "largest_offset_mm": max(offsets) if offsets else 0.0,
            "in_band": float(complete and rms <= band), "cell_time_s": record.cell_time_s,
            "tangential_mean_n": float(np.mean(known)) if known else math.nan,
        })
    return rows


def summary_of(config: CellConfig, spec: PathTaskSpec, path: TaughtPath, probe: PathProbe,
               task: PathTask, rows: list[dict[str, float]], seed: int, wall_s: float,
               cell_time_s: float) -> dict[str, Any]:
    """summary.json of a path run."""
    tail = rows[-END_WINDOW:]
    in_band_at_end = len(tail) == END_WINDOW and all(r["in_band"] for r in tail)
    first_in_band = next((int(r["pass"]) for r in rows if r["in_band"]), None)
    final_rms = statistics.median(r["force_rms_n"] for r in tail) if tail else math.nan
    desired = spec.desired_force_n
    lost = sorted({point for _, point in task.lost_points})
    beyond = int(task.largest_offset_mm > spec.max_deviation_mm + 1e-9)
    diagnosis = "" if in_band_at_end else (
        f"the last {END_WINDOW} passes were not all complete and in band (force RMS <= "
        f"{100 * CONVERGENCE_TOLERANCE:g} % of {desired:.4g} N): see passes.csv")
    at_limit = [k for k, t in enumerate(probe.targets_mm)
                if abs(t) >= spec.max_deviation_mm - 1e-9]
    if at_limit and not in_band_at_end:
        diagnosis = (f"at points {at_limit} the probe's target offset is at max_deviation_mm = "
                     f"{spec.max_deviation_mm:g} mm: the force needs a deeper press than "
                     "allowed (raise task.max_deviation_mm, or check the path's height there)")
    if lost and not in_band_at_end and spec.on_contact_loss == "retreat":
        diagnosis = (f"contact was lost at points {lost} (force under "
                     f"{spec.contact_force_n:.3g} N within max_deviation_mm = "
                     f"{spec.max_deviation_mm:g}) and each such pass ended there "
                     "(on_contact_loss = \"retreat\"): check the part and the path there, or "
                     "set on_contact_loss = \"continue\" to go past a known gap")
    return {
        "task": "path", "path": spec.path, "points": len(path), "seed": seed,
        "robot": config.robot_kind, "sensor": config.sensor_kind,
        "passes": len(rows), "desired_force_n": desired,
        "probe_stiffness_n_per_mm": probe.stiffness_n_per_mm,
        "output_scale_mm": probe.scale_mm, "probe_lost_points": list(probe.lost),
        "probe_targets_mm": list(probe.targets_mm),
        "in_band_at_end": in_band_at_end,
        "first_pass_in_band": first_in_band,
        "warm_start_in_band_within_5": first_in_band is not None and first_in_band < 5,
        "final_force_rms_n": final_rms,
        "final_force_rms_pct": 100.0 * final_rms / desired,
        "failures": int(sum(1 for r in rows if not r["complete"])),
        "on_contact_loss": spec.on_contact_loss,
        "contact_lost_count": len(task.lost_points),
        "contact_lost_points": lost,
        "first_contact_peak_n": task.first_contact_peak_n,
        "tangential_force_n": statistics.median(r["tangential_mean_n"] for r in tail)
        if tail else math.nan,
        "wear_shift_mm": task.output.shift_mm if task.output is not None else 0.0,
        "max_deviation_mm": spec.max_deviation_mm,
        "largest_offset_mm": task.largest_offset_mm,
        "moves_beyond_max_deviation": beyond,
        "cell_time_s": cell_time_s, "wall_s": wall_s,
        "diagnosis": diagnosis,
    }


def end_lines(summary: dict[str, Any], out: Path) -> list[str]:
    """The few lines a path run ends with."""
    lines = [
        f"{summary['passes']} passes over {summary['points']} points, seed {summary['seed']}, "
        f"{summary['robot']} + {summary['sensor']}; failed passes: {summary['failures']}",
        f"{'in band' if summary['in_band_at_end'] else 'NOT in band'} at the end (the last "
        f"{END_WINDOW} passes); first pass in band: {summary['first_pass_in_band']}",
        f"final force RMS {summary['final_force_rms_n']:.3f} N = "
        f"{summary['final_force_rms_pct']:.2f} % of {summary['desired_force_n']:.4g} N",
        f"largest offset {summary['largest_offset_mm']:.2f} mm of max_deviation_mm "
        f"{summary['max_deviation_mm']:g}",
    ]
    if math.isfinite(summary.get("tangential_force_n", math.nan)):
        lines.append(f"tangential force (across the force axis: friction) "
                     f"{summary['tangential_force_n']:.2f} N over the last passes")
    if summary["contact_lost_count"]:
        lines.append(f"contact lost {summary['contact_lost_count']} times, at points "
                     f"{summary['contact_lost_points']} (on_contact_loss = "
                     f"{summary['on_contact_loss']!r})")
    lines.append(f"run directory: {out} (summary.json, trials.csv, passes.csv, steps.csv; "
                 "figures path_forces.png, path_3d.png)")
    return lines
