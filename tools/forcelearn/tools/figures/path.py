"""The path task's figures: the force along the path for chosen passes, the path in 3-D.

``path_forces.png``: the filtered force at every point of the first, a middle
and the last pass, against the desired force and its 5 % band;
``path_3d.png``: the taught points in the base frame (mm), coloured by the
last pass's force error (N); a point where contact was lost is marked x.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from matplotlib.figure import Figure

from forcelearn.atomic import atomic_write_bytes
from forcelearn.trainer import CONVERGENCE_TOLERANCE, TrialLog


def _save(fig: Figure, path: Path) -> Path:
    import io

    buffer = io.BytesIO()
    fig.savefig(buffer, format="png", dpi=110)
    atomic_write_bytes(path, buffer.getvalue())
    return path


def plot_forces(logs: list[TrialLog], desired_n: float, path: Path) -> Path:
    """Force (N) against the point, for the first, a middle and the last pass."""
    fig = Figure(figsize=(7.5, 4.0))
    ax = fig.add_subplot()
    band = CONVERGENCE_TOLERANCE * desired_n
    chosen = sorted({0, len(logs) // 2, len(logs) - 1}) if logs else []
    for index in chosen:
        rows = logs[index].rows
        ax.plot([r["point"] for r in rows], [r["force_n"] for r in rows], marker=".",
                label=f"pass {index}")
    ax.axhline(desired_n, color="k", lw=0.8)
    ax.axhspan(desired_n - band, desired_n + band, color="0.85", label="±5 %")
    ax.set_xlabel("point along the path")
    ax.set_ylabel("force along the tool axis (N)")
    ax.legend(loc="best", fontsize=8)
    return _save(fig, path)


def plot_path_3d(positions_mm: np.ndarray, log: TrialLog, path: Path) -> Path:
    """The taught points (mm), coloured by the pass's force error (N); lost contact: x."""
    fig = Figure(figsize=(6.5, 5.0))
    ax = fig.add_subplot(projection="3d")
    points = np.array([int(r["point"]) for r in log.rows], dtype=int)
    errors = np.array([r["force_error_n"] for r in log.rows])
    lost = np.array([r.get("contact_lost", 0.0) > 0 for r in log.rows], dtype=bool)
    ax.plot(*positions_mm.T, color="0.7", lw=0.8)
    where = positions_mm[points]
    reach = float(np.max(np.abs(errors[~lost]))) if (~lost).any() else 1.0
    shown = ax.scatter(*where[~lost].T, c=errors[~lost], cmap="coolwarm", s=18,
                       vmin=-reach, vmax=reach)
    if lost.any():
        ax.scatter(*where[lost].T, marker="x", color="k", s=30, label="contact lost")
        ax.legend(loc="best", fontsize=8)
    fig.colorbar(shown, ax=ax, shrink=0.7, label="force error (N)")
    ax.set_xlabel("x (mm)")
    ax.set_ylabel("y (mm)")
    ax.set_zlabel("z (mm)")
    return _save(fig, path)
