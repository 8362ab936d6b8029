"""The path task on a cell: probe pass, warm start, passes learned; the run directory.

``forcelearn run`` comes here when the config's ``[task] kind = "path"`` or
``--path FILE`` is given (docs/path.md). The path is read and checked before
the cell opens (a refusal names the file, line or point); then, on the cell of
the config (any robot and sensor kind, emulated or real):

1. the probe pass (:mod:`forcelearn.tasks.path_probe`), which gives the
   stiffness, the output scale and the learner's warm start;
2. ``passes`` passes of the SRV learner over BOXES (the trainer's loop, the
   §5 task's learner and its generalized then specialized phases);
3. the run directory: ``trials.csv`` (one row a pass, the trainer's columns),
   ``passes.csv`` (the path task's own: force RMS over the points in contact,
   contact lost, first-contact peak), ``steps.csv`` (every point of every pass),
   ``probe.csv``, ``summary.json`` and the end lines.

A pass is **in band** when it completes and its force RMS is at most 5 % of the
desired force (the project's band, ``trainer.CONVERGENCE_TOLERANCE``); with
``on_contact_loss = "continue"`` the RMS is over the points in contact (the
points lost are counted apart). The run **ends in band** when its last
``END_WINDOW`` passes are. The final force RMS is their median.
"""

from __future__ import annotations

import logging
import math
import statistics
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from forcelearn.atomic import atomic_write_bytes
from forcelearn.errors import ConfigError, PathRefused
from forcelearn.learning import SRVLearner
from forcelearn.paths import TaughtPath
from forcelearn.run_output import _csv_bytes, write_summary, write_trials
from forcelearn.site import CellConfig, CellSession
from forcelearn.tasks.path import PathGeometry, PathTask, offset_output
from forcelearn.tasks.path_probe import PathProbe, probe_pass, warm_start
from forcelearn.tasks.path_spec import PathTaskSpec, load_task_path
from forcelearn.trainer import CONVERGENCE_TOLERANCE, TrialLog, TrialRecord, train

log = logging.getLogger(__name__)

END_WINDOW = 5
"""Last passes that must all be in band for the run to end in band; the final RMS's window."""
DEFAULT_PASSES = 25
"""Passes of a path run when neither ``--trials`` nor ``[run] trials`` says."""


def load_path(config: CellConfig) -> TaughtPath:
    """The config's path, read, resampled and checked; every point ± max_deviation too."""
    spec = config.path_task
    if spec is None:
        raise ConfigError("this config has no path task: set [task] kind = \"path\" and "
                          "path = FILE, or give forcelearn run --path FILE")
    safety = config.safety
    if config.robot_emulated and config.emulator.part is None:
        raise ConfigError("the path task on the emulated cell needs a part to press: add an "
                          "[emulator.part] table (docs/path.md; examples/paths/*-cell.toml)")
    if spec.desired_force_n + spec.tolerance > safety.max_force_n:
        raise ConfigError(
            f"task.desired_force_n = {spec.desired_force_n:g} N plus its tolerance "
            f"{spec.tolerance:g} N passes safety.max_force_n = {safety.max_force_n:g} N: raise "
            "the limit (FC Pressure's FCSupvForce) or lower the force")
    path = load_task_path(spec, safety.workspace_min_mm, safety.workspace_max_mm,
                          safety.max_step_mm)
    check_deviation(path, spec, safety.workspace_min_mm, safety.workspace_max_mm)
    return path


def check_deviation(path: TaughtPath, spec: PathTaskSpec, low: tuple[float, float, float],
                    high: tuple[float, float, float]) -> None:
    """Refuse a path whose points ± ``max_deviation_mm`` along the force axis leave the box."""
    points = PathGeometry(path, spec.force_axis)
    for k in range(len(points)):
        for sign in (-1.0, 1.0):
            pose = points.pose(k, sign * spec.max_deviation_mm)
            where = np.array([pose.x_mm, pose.y_mm, pose.z_mm])
            if np.any(where < low) or np.any(where > high):
                raise PathRefused(
                    k, path.names[k], path.lines[k],
                    f"{sign * spec.max_deviation_mm:+g} mm along the force axis "
                    f"(task.max_deviation_mm) it would be at "
                    f"({', '.join(f'{v:.6g}' for v in where)}) mm, outside the workspace "
                    "(safety.workspace_min_mm/_max_mm)")


def run_path(config: CellConfig, out: Path, passes: int, seed: int,
             on_pass: Callable[[TrialRecord], Any] | None = None,
             figures: bool = True) -> dict[str, Any]:
    """Probe, learn ``passes`` passes, write the run directory; return the summary.

    ``figures``: also ``path_forces.png`` and ``path_3d.png``
    (:mod:`forcelearn.tools.figures.path`).
    """
    spec = config.path_task
    path = load_path(config)
    assert spec is not None
    out.mkdir(parents=True, exist_ok=True)
    started = time.perf_counter()
    with CellSession(config, seed=seed) as session:
        cell = session.cell
        assert cell is not None
        task = PathTask(cell, spec, path, config.safety.max_step_mm, stiffness_n_per_mm=1.0)
        try:
            probe = probe_pass(task)
            task.output = offset_output(probe.scale_mm, spec.max_deviation_mm)
            learner = SRVLearner(task.grid, 1, config.learner, rng=seed, output=task.output)
            warm_start(learner, probe)
            logs: list[TrialLog] = []

            def after(record: TrialRecord, trial_log: TrialLog, _: SRVLearner) -> None:
                logs.append(trial_log)
                if on_pass is not None:
                    on_pass(record)

            result = train(learner, task, passes, on_trial=after)
        except BaseException:
            cell.stop()
            raise
        cell_time_s = cell.time_s
    wall_s = time.perf_counter() - started
    rows = pass_rows(result.records, logs, spec)
    summary = summary_of(config, spec, path, probe, task, rows, seed, wall_s, cell_time_s)
    summary["moves_outside_workspace"] = outside_workspace(config, spec, path, logs)
    write_trials(out, result.records)
    write_table(out / "passes.csv", rows)
    write_table(out / "steps.csv", [{"pass": float(i), **row} for i, trial_log in enumerate(logs)
                                    for row in trial_log.rows])
    write_table(out / "probe.csv", [
        {"point": float(k), "offset_mm": o, "force_n": f, "target_mm": t, "r_hat": r}
        for k, (o, f, t, r) in enumerate(zip(probe.offsets_mm, probe.forces_n,
                                             probe.targets_mm, probe.r_hats, strict=True))])
    write_summary(out, summary)
    if figures and logs:
        from forcelearn.tools.figures.path import plot_forces, plot_path_3d

        plot_forces(logs, spec.desired_force_n, out / "path_forces.png")
        plot_path_3d(np.asarray(path.positions_mm), logs[-1], out / "path_3d.png")
    return summary


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
        rows.append({
            "pass": float(record.index), "complete": float(complete),
            "force_rms_n": rms, "force_rms_all_n": record.force_rms_n,
            "max_abs_error_n": float(np.max(np.abs(counted))) if counted.size else math.nan,
            "contact_lost": float(lost.sum()), "start_force_n": record.start_force_n,
            "largest_offset_mm": max(offsets) if offsets else 0.0,
            "in_band": float(complete and rms <= band), "cell_time_s": record.cell_time_s,
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
    if summary["contact_lost_count"]:
        lines.append(f"contact lost {summary['contact_lost_count']} times, at points "
                     f"{summary['contact_lost_points']} (on_contact_loss = "
                     f"{summary['on_contact_loss']!r})")
    lines.append(f"run directory: {out} (summary.json, trials.csv, passes.csv, steps.csv; "
                 "figures path_forces.png, path_3d.png)")
    return lines
