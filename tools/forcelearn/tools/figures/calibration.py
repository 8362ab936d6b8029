"""The PNG of a calibration: per-pose residuals of the tool-load fit, noise, matrix check.

``matplotlib.figure.Figure`` only (no pyplot, no global state); written atomically.
"""

from __future__ import annotations

import os

import numpy as np
from matplotlib.figure import Figure

from forcelearn.atomic import atomic_writer
from forcelearn.calibration import AXES, Calibration


def residual_figure(cal: Calibration) -> Figure:
    """Return the figure: force and moment residuals per pose, noise std (and matrix check)."""
    panels = 3 if cal.matrix_check is None else 4
    fig = Figure(figsize=(10, 2.8 * panels), layout="constrained")
    axes = fig.subplots(panels, 1)
    poses = cal.tool.poses
    residual = np.array([p.residual for p in poses])
    x = np.arange(len(poses))
    for ax, cols, unit in ((axes[0], slice(0, 3), "N"), (axes[1], slice(3, 6), "N·m")):
        for k, name in enumerate(AXES[cols]):
            ax.bar(x + (k - 1) * 0.27, residual[:, cols][:, k], width=0.27, label=name)
        ax.axhline(0.0, color="black", linewidth=0.6)
        ax.set_xticks(x, [p.name for p in poses], rotation=20, ha="right", fontsize=7)
        ax.set_ylabel(f"residual ({unit})")
        ax.legend(fontsize=7, ncols=3)
    t = cal.tool
    axes[0].set_title(
        f"tool-load fit: m = {t.mass_kg:.4f} ± {t.mass_std_kg:.4f} kg, "
        f"c = ({', '.join(f'{c:.1f}' for c in t.com_mm)}) mm, "
        f"condition {t.condition_number:.1f}", fontsize=9)
    std = cal.noise.std
    axes[2].bar(AXES, std, color=["C0"] * 3 + ["C1"] * 3)
    axes[2].set_ylabel("noise std (N | N·m)")
    axes[2].set_title(f"noise after zeroing: {cal.noise.samples} samples at "
                      f"{cal.noise.rate_hz:.0f} samples/s", fontsize=9)
    if cal.matrix_check is not None:
        check = cal.matrix_check
        xs = np.arange(6)
        axes[3].bar(xs - 0.2, check.rms_residual_sensor, width=0.4, label="sensor's own")
        axes[3].bar(xs + 0.2, check.rms_residual_fit, width=0.4, label="fitted 6x6")
        axes[3].set_xticks(xs, AXES)
        axes[3].set_ylabel("RMS residual (N | N·m)")
        axes[3].set_title(f"calibration-matrix check over {check.loads} loads", fontsize=9)
        axes[3].legend(fontsize=7)
    return fig


def write_residual_png(cal: Calibration, path: str | os.PathLike[str]) -> None:
    """Write :func:`residual_figure` to ``path`` as PNG, atomically."""
    with atomic_writer(path) as handle:
        residual_figure(cal).savefig(handle, format="png", dpi=110)
