"""Figures of a surface run in the spirit of the paper's Figs. 12-14 (PNG, no pyplot)."""

from __future__ import annotations

from pathlib import Path
from typing import Protocol

import numpy as np
from matplotlib.figure import Figure

from forcelearn.site.config import CellConfig
from forcelearn.tasks.surface import TrialTrace
from forcelearn.trainer import TrainingResult


class SurfaceRun(Protocol):
    """What the figures read of a run.

    (:class:`forcelearn.tools.experiments.surface_state.SurfaceRun`.)
    """

    config: CellConfig
    result: TrainingResult
    traces: list[TrialTrace]

    @property
    def mid_trial(self) -> int:
        """The trial whose step log stands for 'mid-way'."""
        ...


def _save(fig: Figure, path: Path) -> Path:
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    return path


def plot_positions(run: SurfaceRun, path: Path) -> Path:
    """Fig. 12: mean (solid) and searched (dashed) Y commands, and the search width over trials."""
    fig = Figure(figsize=(8, 6))
    top, bottom = fig.subplots(2, 1)
    traces = run.traces
    picks = sorted({0, run.mid_trial, len(traces) - 1} & set(range(len(traces))))
    for index in picks:
        trace = traces[index]
        steps = np.arange(1, len(trace["mean_y_mm"]) + 1)
        line = top.plot(
            steps, trace["mean_y_mm"], "-", marker=".", label=f"trial {index + 1}: mean"
        )
        top.plot(
            steps,
            trace["command_y_mm"],
            "--",
            color=line[0].get_color(),
            lw=0.8,
            label=f"trial {index + 1}: searched",
        )
    top.set_xlabel("step")
    top.set_ylabel("Y command (mm)")
    top.legend(fontsize=7, ncol=2)
    width = [
        float(np.sqrt(np.mean(np.square(np.subtract(t["command_y_mm"], t["mean_y_mm"])))))
        if t["mean_y_mm"]
        else np.nan
        for t in traces
    ]
    bottom.plot(np.arange(1, len(width) + 1), width, ".", ms=3)
    if run.result.switch_trial is not None:
        bottom.axvline(run.result.switch_trial + 1, color="tab:red", ls=":", label="phase switch")
        bottom.legend(fontsize=8)
    bottom.set_yscale("log")
    bottom.set_xlabel("trial")
    bottom.set_ylabel("search width: RMS of\nsearched − mean Y (mm)")
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
