"""The run directory's tables: summary.json, trials.csv and step logs, written atomically.

Shared by every runner (the §5 run, the §4 contour, ``forcelearn sim``);
docs/run-directory.md lists the files and their members. ``summary.json`` holds
at least: task, seed, trials, phase_switch_trial, converged_trial (null when
not reached), final_force_rms_n, final_mean_r, steps, wall_s, steps_per_s.
"""

from __future__ import annotations

import csv
import dataclasses
import io
import json
import math
import statistics
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from forcelearn.atomic import atomic_write_bytes
from forcelearn.trainer import TrialLog, TrialRecord

FINAL_WINDOW = 50
"""Trials over which the final force RMS and mean r are taken (median)."""


def _json_safe(value: Any) -> Any:
    """Replace NaN and infinities (not valid JSON) by None."""
    if isinstance(value, float) and not math.isfinite(value):
        return None
    if isinstance(value, dict):
        return {k: _json_safe(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_json_safe(v) for v in value]
    return value


def summary_text(summary: Mapping[str, Any]) -> str:
    """summary.json's text: indented JSON, non-finite numbers as null, a final newline."""
    return json.dumps(_json_safe(dict(summary)), indent=2, sort_keys=False) + "\n"


def write_summary(folder: Path, summary: Mapping[str, Any]) -> Path:
    """Write summary.json atomically; returns its path."""
    path = folder / "summary.json"
    atomic_write_bytes(path, summary_text(summary).encode())
    return path


def _csv_bytes(header: Sequence[str], rows: Sequence[Sequence[Any]]) -> bytes:
    buffer = io.StringIO()
    writer = csv.writer(buffer, lineterminator="\n")
    writer.writerow(header)
    writer.writerows(rows)
    return buffer.getvalue().encode()


def write_trials(folder: Path, records: Sequence[TrialRecord]) -> Path:
    """Write trials.csv (one row per trial) atomically; returns its path."""
    header = [f.name for f in dataclasses.fields(TrialRecord)]
    rows = [[getattr(r, h) for h in header] for r in records]
    path = folder / "trials.csv"
    atomic_write_bytes(path, _csv_bytes(header, rows))
    return path


def write_step_log(path: Path, log: TrialLog) -> Path:
    """Write one trial's per-step log as CSV atomically."""
    header = list(log.rows[0]) if log.rows else ["step"]
    rows = [[row.get(h, "") for h in header] for row in log.rows]
    atomic_write_bytes(path, _csv_bytes(header, rows))
    return path


def median_range(values: Sequence[float], fmt: str = "{:.0f}") -> str:
    """Format values as 'median (min–max)' for the study reports."""
    return (
        f"{fmt.format(statistics.median(values))} "
        f"({fmt.format(min(values))}–{fmt.format(max(values))})"
    )


def final_figures(records: Sequence[TrialRecord], window: int = FINAL_WINDOW) -> dict[str, float]:
    """Median force RMS and mean r over the last ``window`` trials."""
    tail = records[-window:]
    if not tail:
        return {"final_force_rms_n": math.nan, "final_mean_r": math.nan}

    def median(values: list[float]) -> float:
        finite = [v for v in values if math.isfinite(v)]
        return statistics.median(finite) if finite else math.nan

    return {
        "final_force_rms_n": median([r.force_rms_n for r in tail]),
        "final_mean_r": median([r.mean_r for r in tail]),
    }
