"""The surface probe's figure: force against Y at each probe point, the fits and the chosen map."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from matplotlib.figure import Figure

from forcelearn.tasks.surface_fit import ProbeResult
from forcelearn.tasks.surface_map import OutputMapChoice


def write_probe_figure(probe: ProbeResult, choice: OutputMapChoice | None, path: Path) -> Path:
    """Relaxed (dots) and unrelaxed (crosses) force vs Y per point, fitted lines, output range.

    A map that follows the surface shows the span of its step centres and the start press.
    """
    fig = Figure(figsize=(7, 4.5))
    ax = fig.subplots()
    points = sorted({int(r["point"]) for r in probe.rows})
    for index in points:
        rows = [r for r in probe.rows if r["point"] == index and r["phase"] != "baseline"]
        if not rows:
            continue
        y = np.array([r["y_mm"] for r in rows])
        label = f"z = {rows[0]['z_mm']:g} mm"
        line = ax.plot(y, [r["force_n"] for r in rows], "o", ms=4, label=label)
        color = line[0].get_color()
        ax.plot(y, [r["early_force_n"] for r in rows], "x", ms=4, color=color)
        if index < len(probe.fits):
            fit = probe.fits[index]
            yy = np.linspace(min(y.min(), fit.contact_y_mm - 1), fit.contact_y_mm, 20)
            ax.plot(
                yy,
                fit.stiffness_n_per_mm * (fit.contact_y_mm - yy),
                "-",
                color=color,
                lw=0.8,
                label=f"k = {fit.stiffness_n_per_mm:.2f} N/mm, y_c = {fit.contact_y_mm:.2f} mm",
            )
    if choice is not None and choice.path_y_mm:  # following the surface
        low, high, half = min(choice.path_y_mm), max(choice.path_y_mm), choice.max_offset_mm
        ax.axvspan(low - half, high + half, color="0.93",
                   label=f"output range: ±{half:.1f} mm around each step's centre")
        ax.axvspan(low, high, color="0.8",
                   label=f"step centres, following the surface ({low:.1f} to {high:.1f} mm)")
        if choice.start_press_y_mm is not None:
            ax.axvline(choice.start_press_y_mm, color="k", lw=0.8, ls=":", label="start press")
    elif choice is not None:
        ax.axvline(choice.centre_y_mm, color="k", lw=0.8, ls="--", label="map centre")
        ax.axvspan(
            choice.centre_y_mm - choice.max_offset_mm,
            choice.centre_y_mm + choice.max_offset_mm,
            color="0.9",
            label=f"output range ±{choice.max_offset_mm:.1f} mm",
        )
    ax.set_xlabel("Y command (mm; the sponge is at lower Y)")
    ax.set_ylabel("normal force (N): o relaxed, x at once")
    ax.set_title("surface probe")
    ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    return path
