"""Figures of a surface run in the spirit of the paper's Figs. 12-14 (PNG, no pyplot)."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
from matplotlib.figure import Figure

if TYPE_CHECKING:
    from forcelearn.tools.surface_run import SurfaceRun


def _save(fig: Figure, path: Path) -> Path:
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    return path


def plot_positions(run: SurfaceRun, path: Path) -> Path:
    """Fig. 12: mean (solid) and searched (dashed) Y commands, step after step, over the run."""
    fig = Figure(figsize=(8, 3.8))
    ax = fig.subplots()
    mean, searched, edges = [], [], [0]
    for trace in run.traces:
        mean += trace["mean_y_mm"]
        searched += trace["command_y_mm"]
        edges.append(len(mean))
    steps = np.arange(1, len(mean) + 1)
    ax.plot(steps, searched, "--", lw=0.6, color="tab:orange", label="searched Y command")
    ax.plot(steps, mean, "-", lw=1.0, color="tab:blue", label="mean Y (μ)")
    if run.result.switch_trial is not None and run.result.switch_trial + 1 < len(edges):
        ax.axvline(
            edges[run.result.switch_trial + 1], color="tab:red", ls=":", label="phase switch"
        )
    ax.set_xlabel("control step (all trials in order)")
    ax.set_ylabel("Y position command (mm)")
    ax.legend(fontsize=8, loc="lower left")
    return _save(fig, path)


def plot_forces(run: SurfaceRun, path: Path) -> Path:
    """Fig. 13: contact force per step at the first trial, mid-way and at the end."""
    fig = Figure(figsize=(7, 3.8))
    ax = fig.subplots()
    result = run.result
    for trial_log, style in (
        (result.first_log, ":"),
        (result.logs.get(run.mid_trial), "--"),
        (result.last_log, "-"),
    ):
        if trial_log is None or not trial_log.rows:
            continue
        steps = [row["step"] for row in trial_log.rows]
        ax.plot(
            steps,
            [row["force_n"] for row in trial_log.rows],
            style,
            marker=".",
            label=f"trial {trial_log.index + 1}",
        )
    desired = run.config.task.desired_force_n
    ax.axhline(desired, color="k", lw=0.8, label=f"desired {desired:.2f} N")
    ax.axhspan(0.95 * desired, 1.05 * desired, color="0.9", label="±5 % band")
    ax.set_xlim(0.5, run.config.task.steps_per_trial + 0.5)
    ax.set_xlabel("step")
    ax.set_ylabel("contact force (N)")
    ax.legend(fontsize=8)
    return _save(fig, path)


def plot_initial_force(run: SurfaceRun, path: Path) -> Path:
    """Fig. 14: contact force at the start pose against repetition (the sponge wears)."""
    fig = Figure(figsize=(7, 3.5))
    ax = fig.subplots()
    records = run.result.records
    ax.plot([r.index + 1 for r in records], [r.start_force_n for r in records], ".-", ms=3)
    ax.set_xlabel("repetition")
    ax.set_ylabel("initial contact force (N)")
    return _save(fig, path)


def write_all(run: SurfaceRun, folder: Path) -> list[Path]:
    """Write the three figures into ``folder``."""
    return [
        plot_positions(run, folder / "fig12_positions.png"),
        plot_forces(run, folder / "fig13_contact_force.png"),
        plot_initial_force(run, folder / "fig14_initial_force.png"),
    ]
