"""Figure and table of the surface study over the cell's timing (docs/results/surface-timing.md).

Reads a finished ``forcelearn study surface`` folder swept over three keys (by default the
study's own order: servo lag, arm speed, baud rate) and draws, for each value of the third key,
a column of three heatmaps over the first two: the median trial of convergence (a run that never
converged counts as the trial budget), the median final force RMS (N) and the median cell time
of a run (h), medians over the seeds. Prints the per-point Markdown table of the page::

    python -m forcelearn.tools.results.surface_timing /tmp/timing-study/grid \
        [--out docs/results/surface_timing.png]
"""

from __future__ import annotations

import argparse
import json
import math
import statistics
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from forcelearn.errors import StudyError

DEFAULT_OUT = Path("docs/results/surface_timing.png")
PANELS = (
    ("converged_trial", "median trial of convergence", "viridis"),
    ("final_force_rms_n", "median final force RMS, N", "cividis"),
    ("cell_time_h", "median cell time of a run, h", "magma"),
)


def _order(value: str) -> tuple[int, float, str]:
    """Sort key of a formatted grid value: numbers by value, anything else after them."""
    try:
        return (0, float(value), value)
    except ValueError:
        return (1, math.nan, value)


def load_study(folder: Path) -> tuple[list[str], int, list[dict[str, Any]]]:
    """The swept keys, the trial budget and the run rows of a finished study folder.

    Raises:
        StudyError: the folder holds no study, a run is missing, or the study does not sweep
            exactly three keys.
    """
    manifest_path = folder / "study.json"
    if not manifest_path.is_file():
        raise StudyError(
            f"{folder} holds no study (no study.json): give the --out folder of "
            "`forcelearn study surface`"
        )
    manifest = json.loads(manifest_path.read_text())
    keys = list(manifest["keys"])
    if len(keys) != 3:
        raise StudyError(
            f"{folder} sweeps {len(keys)} keys ({', '.join(keys) or 'none'}); this figure needs "
            "three: panel rows, panel columns, one column of panels per value of the third"
        )
    rows = [json.loads(p.read_text()) for p in sorted((folder / "runs").glob("*.json"))]
    wanted = len(manifest["points"]) * len(manifest["seeds"])
    if len(rows) < wanted:
        raise StudyError(
            f"{folder} holds {len(rows)} of the study's {wanted} runs: run its command again "
            "to finish it (finished runs are kept)"
        )
    return keys, int(manifest["trials"]), rows


def _figure(row: dict[str, Any], name: str, trials: int) -> float:
    """One run's value of a panel's figure (never converged = the trial budget)."""
    if name == "converged_trial":
        return float(trials if row["converged_trial"] is None else row["converged_trial"])
    if name == "cell_time_h":
        return float(row["cell_time_s"]) / 3600.0
    value = row[name]
    return math.nan if value is None else float(value)


def panel(
    keys: Sequence[str], trials: int, rows: Sequence[dict[str, Any]], name: str, col: str
) -> tuple[list[list[float]], list[list[str]]]:
    """One heatmap's medians over seeds and cell labels, for the runs whose third key is ``col``.

    Rows of the grid are the first key's values, columns the second's, both in ascending order.
    """
    y_key, x_key, col_key = keys
    ys, xs = (sorted({str(r[k]) for r in rows}, key=_order) for k in (y_key, x_key))
    grid = [[math.nan] * len(xs) for _ in ys]
    notes = [[""] * len(xs) for _ in ys]
    for i, vy in enumerate(ys):
        for j, vx in enumerate(xs):
            point = (vy, vx, col)
            runs = [r for r in rows if (str(r[y_key]), str(r[x_key]), str(r[col_key])) == point]
            values = [v for v in (_figure(r, name, trials) for r in runs) if math.isfinite(v)]
            grid[i][j] = statistics.median(values) if values else math.nan
            if name == "converged_trial":
                done = sum(r["converged_trial"] is not None for r in runs)
                notes[i][j] = f"{grid[i][j]:g}\n{done}/{len(runs)} conv."
            elif name == "cell_time_h":
                notes[i][j] = f"{grid[i][j]:.2f} h"
            else:
                notes[i][j] = f"{grid[i][j]:.3f}"
    return grid, notes


def plot(keys: Sequence[str], trials: int, rows: Sequence[dict[str, Any]], out: Path) -> Path:
    """Draw the 3 × (values of the third key) heatmaps and save them as PNG."""
    y_key, x_key, col_key = keys
    ys, xs, cols = (sorted({str(r[k]) for r in rows}, key=_order) for k in keys)
    seeds = sorted({int(r["seed"]) for r in rows})
    fig = Figure(figsize=(3.6 * len(cols) + 1.0, 9.2))
    FigureCanvasAgg(fig)
    axes = fig.subplots(len(PANELS), len(cols), squeeze=False)
    for p, (name, label, cmap) in enumerate(PANELS):
        every = [_figure(r, name, trials) for r in rows]
        finite = [v for v in every if math.isfinite(v)]
        top = float(trials) if name == "converged_trial" else max(finite, default=0.0) or 1.0
        for c, col in enumerate(cols):
            ax = axes[p][c]
            grid, notes = panel(keys, trials, rows, name, col)
            image = ax.imshow(grid, origin="lower", aspect="auto", cmap=cmap, vmin=0.0,
                              vmax=top)
            fig.colorbar(image, ax=ax)
            for i in range(len(ys)):
                for j in range(len(xs)):
                    ax.text(j, i, notes[i][j], ha="center", va="center", fontsize=8,
                            color="w" if grid[i][j] < 0.6 * top else "k")
            ax.set_xticks(range(len(xs)), xs)
            ax.set_yticks(range(len(ys)), ys)
            ax.set_xlabel(x_key)
            ax.set_ylabel(y_key)
            ax.set_title(f"{col_key.rsplit('.', 1)[-1]} {col}: {label}", fontsize=9)
    fig.suptitle(
        f"Emulated §5 cell over {y_key} × {x_key} × {col_key}: {len(rows)} runs, "
        f"seed{'s' if len(seeds) > 1 else ''} {', '.join(map(str, seeds))}, {trials} trials "
        "each\n(median over seeds; a run that "
        f"never converged counts as {trials})",
        fontsize=10,
    )
    fig.tight_layout()
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=100)
    return out


def table(keys: Sequence[str], trials: int, rows: Sequence[dict[str, Any]]) -> list[str]:
    """The per-point Markdown table: each figure listed per seed, seeds in order."""
    header = [*(k.rsplit(".", 1)[-1] for k in keys), "converged", "converged trial",
              "final force RMS N", "failed trials", "trials out of band after convergence",
              "cell time of a run h"]
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    points = sorted({tuple(str(r[k]) for k in keys) for r in rows},
                    key=lambda p: tuple(_order(v) for v in p))
    for point in points:
        runs = sorted((r for r in rows if tuple(str(r[k]) for k in keys) == point),
                      key=lambda r: int(r["seed"]))

        def each(name: str, fmt: str, runs: list[dict[str, Any]] = runs) -> str:
            return ", ".join("–" if r.get(name) is None else fmt.format(r[name]) for r in runs)

        done = sum(r["converged_trial"] is not None for r in runs)
        hours = ", ".join(f"{float(r['cell_time_s']) / 3600:.2f}" for r in runs)
        cells = [*point, f"{done} / {len(runs)}", each("converged_trial", "{}"),
                 each("final_force_rms_n", "{:.3f}"), each("failures", "{}"),
                 each("trials_out_of_band_after_convergence", "{}"), hours]
        lines.append("| " + " | ".join(cells) + " |")
    return lines


def main(argv: Sequence[str] | None = None) -> int:
    """Read the study, draw the figure, print the table."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("study", type=Path, help="the study's folder (its --out)")
    parser.add_argument("--out", type=Path, default=DEFAULT_OUT, help="PNG to write")
    args = parser.parse_args(argv)
    keys, trials, rows = load_study(args.study)
    print("\n".join(table(keys, trials, rows)))
    print(f"figure: {plot(keys, trials, rows, args.out)}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
