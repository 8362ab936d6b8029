"""Figures of a contour run in the spirit of the paper's Figs. 5-10 (PNG, matplotlib Agg)."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np
from matplotlib.figure import Figure

from forcelearn.emulators.physics.two_link_arm import ContourGeometry, forward_kinematics
from forcelearn.trainer import TrainingResult, TrialLog


def moving_average(values: np.ndarray, window: int = 10) -> np.ndarray:
    """Trailing moving average over ``window`` values (shorter at the start)."""
    cumulative = np.cumsum(np.insert(values.astype(float), 0, 0.0))
    out = np.empty(len(values))
    for i in range(len(values)):
        lo = max(0, i + 1 - window)
        out[i] = (cumulative[i + 1] - cumulative[lo]) / (i + 1 - lo)
    return out


def _column(log: TrialLog, key: str) -> np.ndarray:
    return np.array([row[key] for row in log.rows], dtype=float)


def _figure(
    rows: int = 1, figsize: tuple[float, float] = (7, 3.5), sharex: bool = False
) -> tuple[Figure, Any]:
    """A pyplot-free figure (no global backend state) and its axes (one Axes, or an array)."""
    fig = Figure(figsize=figsize)
    return fig, fig.subplots(rows, 1, sharex=sharex)


def _save(fig: Figure, path: Path) -> Path:
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    return path


def plot_geometry(geometry: ContourGeometry, path: Path, log: TrialLog | None = None) -> Path:
    """Fig. 5 / Fig. 10: the arm at its start pose, the surface, and a learned tool path."""
    fig, ax = _figure(figsize=(6, 5))
    cx, cy = geometry.centre_m
    angles = np.linspace(0, 2 * math.pi, 400)
    ax.plot(
        cx + geometry.radius_m * np.cos(angles),
        cy + geometry.radius_m * np.sin(angles),
        "k--",
        lw=1,
        label="surface (100 N/m)",
    )
    t1, t2 = geometry.start_theta_deg
    elbow = (
        geometry.link1_m * math.cos(math.radians(t1)),
        geometry.link1_m * math.sin(math.radians(t1)),
    )
    tip = forward_kinematics(geometry, t1, t2)
    ax.plot(
        [0, elbow[0], tip[0]],
        [0, elbow[1], tip[1]],
        "o-",
        color="tab:blue",
        lw=3,
        label="arm at start (45°, −45°)",
    )
    if log is not None and log.rows:
        ax.plot(
            _column(log, "tip_x_m"),
            _column(log, "tip_y_m"),
            "-",
            color="tab:red",
            lw=2,
            label=f"tool path, trial {log.index}",
        )
    ax.set_aspect("equal")
    ax.set_xlim(-0.1, cx + 0.2)
    ax.set_ylim(-0.35, 1.3)
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.set_title("Two-link arm and circular surface")
    ax.legend(loc="upper left", fontsize=8)
    return _save(fig, path)


def plot_steps(result: TrainingResult, steps_per_trial: int, path: Path) -> Path:
    """Fig. 6: steps completed per repetition with a 10-trial moving average."""
    steps = np.array([r.steps for r in result.records])
    fig, ax = _figure()
    ax.plot(steps, ".", ms=2, color="0.6", label="steps per trial")
    ax.plot(moving_average(steps), color="tab:blue", label="10-trial moving average")
    if result.switch_trial is not None:
        ax.axvline(result.switch_trial, color="tab:red", ls=":", label="phase switch")
    ax.set_ylim(0, steps_per_trial + 2)
    ax.set_xlabel("repetition")
    ax.set_ylabel("steps completed")
    ax.legend(fontsize=8)
    return _save(fig, path)


def _switch_and_final(result: TrainingResult) -> list[tuple[TrialLog, str, str]]:
    pairs = []
    if result.switch_log is not None:
        pairs.append((result.switch_log, "--", f"at switch (trial {result.switch_log.index})"))
    if result.last_log is not None:
        pairs.append((result.last_log, "-", f"final (trial {result.last_log.index})"))
    return pairs


def plot_joint_trajectories(result: TrainingResult, path: Path) -> Path:
    """Fig. 7: learned joint trajectories θ1 and θ2 per step."""
    fig, axes = _figure(2, figsize=(7, 5), sharex=True)
    for log, style, label in _switch_and_final(result):
        for ax, key, name in zip(axes, ("theta1_deg", "theta2_deg"), ("θ1", "θ2"), strict=True):
            ax.plot(_column(log, "step"), _column(log, key), style, label=label)
            ax.set_ylabel(f"{name} (deg)")
    axes[0].legend(fontsize=8)
    axes[1].set_xlabel("step")
    return _save(fig, path)


def plot_step_series(result: TrainingResult, key: str, ylabel: str, path: Path) -> Path:
    """Figs. 8-9: a per-step series at the switch (dashed) and at the end (solid)."""
    fig, ax = _figure()
    for log, style, label in _switch_and_final(result):
        ax.plot(_column(log, "step"), _column(log, key), style, label=label)
    ax.axhline(0, color="0.7", lw=0.8)
    ax.set_xlabel("step")
    ax.set_ylabel(ylabel)
    ax.legend(fontsize=8)
    return _save(fig, path)


def write_all(
    result: TrainingResult, geometry: ContourGeometry, steps_per_trial: int, folder: Path
) -> list[Path]:
    """Write every contour figure into ``folder``; return their paths."""
    return [
        plot_geometry(geometry, folder / "fig05_10_geometry_and_path.png", result.last_log),
        plot_steps(result, steps_per_trial, folder / "fig06_steps_per_trial.png"),
        plot_joint_trajectories(result, folder / "fig07_joint_trajectories.png"),
        plot_step_series(result, "r", "evaluation r", folder / "fig08_evaluation.png"),
        plot_step_series(
            result, "force_error_n", "force error (N)", folder / "fig09_force_error.png"
        ),
    ]
