"""The surface run's outputs: summary.json, trials.csv, the step logs, the probe files, figures.

Written from a :class:`~forcelearn.tools.experiments.surface_state.SurfaceRun`
when the run ends (or stops), each file atomically; docs/run-directory.md lists
them and the summary's members.
"""

from __future__ import annotations

import csv
import dataclasses
import json
import math
from pathlib import Path
from typing import Any

from forcelearn.learning import SRVLearner
from forcelearn.run_output import (
    FINAL_WINDOW,
    final_figures,
    write_step_log,
    write_summary,
    write_trials,
)
from forcelearn.tasks.surface_diagnosis import RunEvidence, StuckMonitor, diagnose
from forcelearn.tasks.surface_map import OutputMapChoice
from forcelearn.tasks.surface_probe import ProbeResult
from forcelearn.tools.experiments.fault_recovery import fault_summary
from forcelearn.tools.experiments.surface_state import SurfaceRun
from forcelearn.trainer import (
    CONVERGENCE_TOLERANCE,
    CONVERGENCE_WINDOW,
    converged_trial,
    criterion_trial,
)

FIGURES = (
    "fig12_positions.png", "fig13_contact_force.png", "fig14_initial_force.png", "probe.png"
)
"""The figures a run directory may hold, in the order a person looks at them."""


def write_probe_files(
    out: Path, probe: ProbeResult, choice: OutputMapChoice | None
) -> None:
    """probe.csv (every reading), probe.json (fits and map) and probe.png (the figure)."""
    from forcelearn.tools.figures import probe as figures_probe

    out.mkdir(parents=True, exist_ok=True)
    with open(out / "probe.csv", "w", newline="") as handle:
        fields = ["point", "z_mm", "y_mm", "phase", "early_force_n", "force_n", "cell_time_s"]
        writer = csv.DictWriter(handle, fieldnames=fields)
        writer.writeheader()
        writer.writerows(probe.rows)
    data = {**probe.to_json(), "output_map": dataclasses.asdict(choice) if choice else None}
    del data["rows"]
    (out / "probe.json").write_text(json.dumps(data, indent=2))
    if probe.rows:
        figures_probe.write_probe_figure(probe, choice, out / "probe.png")


def summary_of(run: SurfaceRun, learner: SRVLearner) -> dict[str, Any]:
    """The run's summary.json content."""
    result, config = run.result, run.config
    cell_time = float(sum(r.cell_time_s for r in result.records))
    converged_at = converged_trial(
        result.records, config.task.steps_per_trial, config.task.desired_force_n
    )
    monitor = run.monitor or StuckMonitor(0.0, 1.0, config.task.steps_per_trial)
    tail = run.traces[-CONVERGENCE_WINDOW:]
    evidence = RunEvidence(
        config.task.desired_force_n, [t["command_y_mm"] for t in tail],
        [t["force_n"] for t in tail], [r.force_rms_n for r in result.records], run.probe,
        run.output_map.approach_mm if run.output_map is not None else 0.0,
    )
    verdict = diagnose(
        result.records, converged_at, monitor, config.task.desired_force_n, run.feasibility,
        evidence=evidence,
    )
    warnings = list(monitor.warnings)
    if run.feasibility is not None:
        warnings.append(run.feasibility.text())
    return {
        "task": "surface",
        "seed": run.seed,
        "learner_start": run.learner_start,
        "trials": len(result.records),
        "phase_switch_trial": result.switch_trial,
        "criterion_trial": criterion_trial(result.records, config.learner.success_trials),
        "converged_trial": converged_at,
        **verdict,
        "feasibility": {
            "out_of_reach_at_end": run.feasibility_now,
            "first_trial": run.feasibility_first_trial,
            "latest": dataclasses.asdict(run.feasibility) if run.feasibility else None,
        },
        "warnings": warnings,
        "output_map": dataclasses.asdict(run.output_map) if run.output_map else None,
        "map_shift_mm": run.map_shift_mm,
        "map_recentre_mm": run.map_recentre_mm,
        "wear_reference_n": run.wear_reference_n,
        "tares": {"done": run.tares[0], "refused": run.tares[1]},
        "probe_stiffness_n_per_mm": (
            run.probe.stiffness_n_per_mm() if run.probe is not None else None
        ),
        "probe_fits": (
            [dataclasses.asdict(f) for f in run.probe.fits] if run.probe is not None else None
        ),
        **final_figures(result.records),
        "failures": sum(r.failed for r in result.records),
        "desired_force_n": config.task.desired_force_n,
        "emulated": config.robot_emulated and config.sensor_emulated,
        "steps": result.steps,
        "wall_s": round(run.wall_s, 3),
        "steps_per_s": round(result.steps / run.wall_s, 1) if run.wall_s > 0 else None,
        "cell_time_s": round(cell_time, 3),
        "realtime_factor": round(cell_time / run.wall_s, 1) if run.wall_s > 0 else None,
        "profile": config.emulator.profile if config.robot_emulated else None,
        "faults": fault_summary(run.out),
    }


def write_outputs(run: SurfaceRun, learner: SRVLearner) -> dict[str, Any]:
    """Write summary.json, trials.csv, the step logs and the figures; return the summary."""
    from forcelearn.tools.figures import surface as figures_surface

    summary = summary_of(run, learner)
    write_summary(run.out, summary)
    write_trials(run.out, run.result.records)
    result = run.result
    named = {
        "first": result.first_log,
        "switch": result.switch_log,
        "final": result.last_log,
        "mid": result.logs.get(run.mid_trial),
    }
    for name, trial_log in named.items():
        if trial_log is not None:
            write_step_log(run.out / f"steps_{name}.csv", trial_log)
    if result.records:
        figures_surface.write_all(run, run.out)
    return summary


def end_lines(summary: dict[str, Any], out: Path) -> list[str]:
    """What a person reads at the end of a run: the verdict, the final force, where the files are.

    Args:
        summary: the run's summary (:func:`summary_of`).
        out: the run directory.
    """
    trials, failures = summary["trials"], summary["failures"]
    start = {"probe": "warm start from the probe", "cold": "cold start"}.get(
        summary["learner_start"], f"{summary['learner_start']} start"
    )
    at = summary["converged_trial"]
    converged = f"not converged in {trials} trials" if at is None else f"converged at trial {at}"
    band = "in band" if summary["in_band_at_end"] else "NOT in band"
    desired, rms = summary["desired_force_n"], summary["final_force_rms_n"]
    rms_text = f"{rms:.3f} N" if rms is not None and math.isfinite(rms) else "none (no step)"
    lines = [
        f"{trials} trials, seed {summary['seed']}, {start}; failed trials: {failures}",
        f"{converged}; {band} at the end (the last {CONVERGENCE_WINDOW} trials)",
        f"final force RMS {rms_text} against the band of {CONVERGENCE_TOLERANCE * desired:.3f} N "
        f"({CONVERGENCE_TOLERANCE * 100:g} % of {desired:.2f} N; median of the last "
        f"{min(trials, FINAL_WINDOW)} trials)",
    ]
    if summary["diagnosis"]:
        lines.append(f"diagnosis: {summary['diagnosis']}")
    lines.append(f"run directory: {out}")
    figures = [name for name in FIGURES if (out / name).exists()]
    if figures:
        lines.append(f"  figures: {', '.join(figures)}")
    lines.append("  every number: summary.json (forcelearn run --json prints it)")
    return lines
