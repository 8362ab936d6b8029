"""A study's tables and figures: runs.csv, summary.csv, summary.md, one heatmap per swept pair.

``runs.csv`` is tidy: one row per run with every parameter (dotted keys) and
every summary figure. ``summary.csv`` has one row per grid point: for the
trial counts, how many seeds reached them and the median / min / max with a
run that never reached them counted as the budget; for the other figures the
median / min / max over seeds. A heatmap per pair of swept keys shows the
median over seeds (and over any other swept keys) of the trials to
convergence and of the final force RMS.
"""

from __future__ import annotations

import csv
import io
import itertools
import math
import statistics
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from forcelearn.atomic import atomic_write_bytes

TRIAL_FIGURES = ("criterion_trial", "converged_trial")
"""Trial counts that may be never reached (None); counted as the budget in medians."""
VALUE_FIGURES = ("final_force_rms_n", "greedy_force_rms_n", "final_mean_r", "failures")
HEATMAPS = (
    ("converged_trial", "trials to convergence"),
    ("final_force_rms_n", "final force RMS (N)"),
)


def _csv(path: Path, header: Sequence[str], rows: Sequence[dict[str, Any]]) -> Path:
    buffer = io.StringIO()
    writer = csv.DictWriter(buffer, header, lineterminator="\n", extrasaction="ignore")
    writer.writeheader()
    writer.writerows(rows)
    atomic_write_bytes(path, buffer.getvalue().encode())
    return path


def _stats(values: Sequence[float | None]) -> tuple[float, float, float]:
    finite = [v for v in values if v is not None and math.isfinite(v)]
    if not finite:
        return math.nan, math.nan, math.nan
    return statistics.median(finite), min(finite), max(finite)


def summarize(
    rows: Sequence[dict[str, Any]], keys: Sequence[str], trials: int
) -> list[dict[str, Any]]:
    """One summary row per grid point, in the order the points first appear."""
    points: dict[tuple[Any, ...], list[dict[str, Any]]] = {}
    for row in rows:
        points.setdefault(tuple(row[k] for k in keys), []).append(row)
    summary = []
    for point, runs in points.items():
        entry: dict[str, Any] = dict(zip(keys, point, strict=True))
        entry["runs"] = len(runs)
        for name in TRIAL_FIGURES:
            found = [r.get(name) for r in runs]
            entry[f"{name}_reached"] = sum(v is not None for v in found)
            counted = [float(trials if v is None else v) for v in found]
            entry[f"{name}_median"], entry[f"{name}_min"], entry[f"{name}_max"] = _stats(counted)
        for name in VALUE_FIGURES:
            values = [r.get(name) for r in runs]
            entry[f"{name}_median"], entry[f"{name}_min"], entry[f"{name}_max"] = _stats(values)
        summary.append(entry)
    return summary


def markdown(summary: Sequence[dict[str, Any]], keys: Sequence[str], trials: int) -> list[str]:
    """The summary as a Markdown table (medians with ranges)."""
    head = [
        *keys,
        "runs",
        "criterion reached",
        f"trials to criterion (never = {trials})",
        "converged",
        f"trials to convergence (never = {trials})",
        "final force RMS (N)",
        "μ-only force RMS (N)",
    ]
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]

    def span(entry: dict[str, Any], name: str, fmt: str) -> str:
        return (
            f"{fmt.format(entry[name + '_median'])} "
            f"({fmt.format(entry[name + '_min'])}–{fmt.format(entry[name + '_max'])})"
        )

    for e in summary:
        cells = [str(e[k]) for k in keys] + [
            str(e["runs"]),
            f"{e['criterion_trial_reached']}/{e['runs']}",
            span(e, "criterion_trial", "{:.0f}"),
            f"{e['converged_trial_reached']}/{e['runs']}",
            span(e, "converged_trial", "{:.0f}"),
            span(e, "final_force_rms_n", "{:.3f}"),
            span(e, "greedy_force_rms_n", "{:.3f}"),
        ]
        lines.append("| " + " | ".join(cells) + " |")
    return lines


def _heatmap(rows: Sequence[dict[str, Any]], x: str, y: str, trials: int, path: Path) -> Path:
    from matplotlib.figure import Figure

    xs = list(dict.fromkeys(r[x] for r in rows))
    ys = list(dict.fromkeys(r[y] for r in rows))
    fig = Figure(figsize=(5.2 * len(HEATMAPS), 4.2))
    for ax, (name, label) in zip(fig.subplots(1, len(HEATMAPS)), HEATMAPS, strict=True):
        grid = [[math.nan] * len(xs) for _ in ys]
        for (i, vy), (j, vx) in itertools.product(enumerate(ys), enumerate(xs)):
            values = [r.get(name) for r in rows if r[x] == vx and r[y] == vy]
            if name in TRIAL_FIGURES:
                values = [float(trials if v is None else v) for v in values]
            grid[i][j] = _stats(values)[0]
        image = ax.imshow(grid, origin="lower", aspect="auto", cmap="viridis")
        fig.colorbar(image, ax=ax, label=f"median {label}")
        for (i, _), (j, _) in itertools.product(enumerate(ys), enumerate(xs)):
            fmt = "{:.0f}" if name in TRIAL_FIGURES else "{:.3f}"
            ax.text(j, i, fmt.format(grid[i][j]), ha="center", va="center", color="w", fontsize=7)
        ax.set_xticks(range(len(xs)), [str(v) for v in xs])
        ax.set_yticks(range(len(ys)), [str(v) for v in ys])
        ax.set_xlabel(x)
        ax.set_ylabel(y)
        ax.set_title(f"median {label}" + (f" (never = {trials})" if name in TRIAL_FIGURES else ""))
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    return path


def write_tables(
    out: Path, rows: Sequence[dict[str, Any]], keys: Sequence[str], trials: int, command: str = ""
) -> list[Path]:
    """Write runs.csv, summary.csv, summary.md and the heatmaps; return the paths written."""
    header = list(dict.fromkeys(k for row in rows for k in row))
    files = [_csv(out / "runs.csv", header, rows)]
    summary = summarize(rows, keys, trials)
    files.append(_csv(out / "summary.csv", list(summary[0]) if summary else keys, summary))
    text = [f"Made by `{command}`." if command else "", "", *markdown(summary, keys, trials), ""]
    path = out / "summary.md"
    atomic_write_bytes(path, "\n".join(text).encode())
    files.append(path)
    swept = [k for k in keys if len({r[k] for r in rows}) > 1]
    for x, y in itertools.combinations(swept, 2):
        name = f"heatmap_{x}__{y}.png".replace(".", "-").replace("-png", ".png")
        files.append(_heatmap(rows, x, y, trials, out / name))
    return files
