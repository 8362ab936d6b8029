"""The page and figure of the real-foam study (:mod:`forcelearn.tools.results.materials`)."""

from __future__ import annotations

import csv
import json
import math
import statistics
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from forcelearn.trainer import CONVERGENCE_TOLERANCE

STIFF_N_PER_MM = 5.0
"""A cell at least this stiff counts as a stiff part (the real-foam study's stiff cells), N/mm."""


@dataclass(frozen=True)
class CellRun:
    """One finished run of the study, with its cell's truth."""

    cell: str
    start: str
    approach: str
    stiffness_n_per_mm: float
    desired_force_n: float
    hysteresis_loss: float
    stiffening_exponent: float
    friction_coefficient: float
    noise_n: float
    waviness_mm: float
    converged_trial: int | None
    """summary.json's ``converged_trial`` (0: the first trial); None: never."""
    in_band_at_end: bool
    failed_trials: int
    force_rms_n: tuple[float, ...]
    """Every trial's force RMS, N."""
    diagnosis: str | None
    approach_mm: float

    @property
    def band_n(self) -> float:
        """The convergence band: 5 % of the desired force, N."""
        return CONVERGENCE_TOLERANCE * self.desired_force_n

    @property
    def hysteretic(self) -> bool:
        """The cell's foam is hysteretic (truth)."""
        return self.hysteresis_loss > 0

    @property
    def stiff(self) -> bool:
        """The cell is a stiff part (truth)."""
        return self.stiffness_n_per_mm >= STIFF_N_PER_MM


def read_run(run_dir: Path, cell: str, start: str, approach: str, truth: dict[str, Any]) -> CellRun:
    """A finished run directory and its cell's truth as a :class:`CellRun`."""
    summary = json.loads((run_dir / "summary.json").read_text(encoding="utf-8"))
    with (run_dir / "trials.csv").open(newline="") as handle:
        rows = list(csv.DictReader(handle))
    sponge = truth["sponge"]
    converged = summary.get("converged_trial") if summary.get("converged") else None
    return CellRun(
        cell, start, approach, float(sponge["stiffness_n_per_mm"]),
        float(truth["task"]["desired_force_n"]), float(sponge["hysteresis_loss"]),
        float(sponge["stiffening_exponent"]), float(sponge["friction_coefficient"]),
        float(truth["sensor"]["noise_n"]), float(sponge["waviness_mm"]),
        None if converged is None else int(converged), bool(summary.get("in_band_at_end")),
        sum(row["failed"] in ("1", "True", "true") for row in rows),
        tuple(float(row["force_rms_n"]) for row in rows), summary.get("diagnosis"),
        float((summary.get("output_map") or {}).get("approach_mm") or 0.0),
    )


def _median_converged(runs: Sequence[CellRun], budget: int) -> float:
    """Median trial of convergence; a run that never converged counts as ``budget``."""
    if not runs:
        return math.nan
    return statistics.median(budget if r.converged_trial is None else r.converged_trial
                             for r in runs)


def headline(runs: Sequence[CellRun], trials: int) -> list[str]:
    """The page's first lines: the issue's targets against what the runs did."""
    lines = []
    for start in ("probe", "cold"):
        chosen = [r for r in runs if r.start == start and r.approach == "auto"]
        if not chosen:
            continue
        ends = sum(r.in_band_at_end for r in chosen)
        hyst = [r for r in chosen if r.hysteretic]
        stiff = [r for r in chosen if r.stiff]
        most_failed = max((r.failed_trials for r in stiff), default=0)
        lines.append(
            f"- **start {start!r}**: {ends} of {len(chosen)} cells end in band within {trials} "
            f"trials; median trial of convergence on the {len(hyst)} hysteretic cells "
            f"{_median_converged(hyst, trials):g} (never: counted as {trials}); failed trials "
            f"on the {len(stiff)} stiff cells (>= {STIFF_N_PER_MM:g} N/mm): at most "
            f"{most_failed} per run")
    for approach in sorted({r.approach for r in runs} - {"auto"}):
        same = [r for r in runs if r.approach == approach]
        auto = [r for r in runs if r.approach == "auto" and r.start == "probe"
                and r.cell in {s.cell for s in same}]
        lines.append(
            f"- **approach {approach!r}** on the same {len(same)} hysteretic cells (start "
            f"'probe'): {sum(r.in_band_at_end for r in same)} end in band, median convergence "
            f"{_median_converged(same, trials):g}; the default ('auto'): "
            f"{sum(r.in_band_at_end for r in auto)} and {_median_converged(auto, trials):g}")
    return lines


def _row(r: CellRun) -> str:
    final = statistics.fmean(r.force_rms_n[-10:]) / r.band_n if r.force_rms_n else math.nan
    converged = "—" if r.converged_trial is None else str(r.converged_trial)
    diagnosis = (r.diagnosis or "").replace("|", "/")
    return (f"| {r.cell} | {r.start} | {r.approach} | {r.stiffness_n_per_mm:.2f} | "
            f"{r.desired_force_n:.1f} | {r.hysteresis_loss:.2f} | {r.stiffening_exponent:.2f} | "
            f"{r.friction_coefficient:.2f} | {r.noise_n:.2f} | {r.approach_mm:.1f} | {converged} | "
            f"{'yes' if r.in_band_at_end else 'no'} | {r.failed_trials} | {final:.2f} | "
            f"{diagnosis} |")


def write_page(
    runs: Sequence[CellRun], page: Path, figure: Path, seed: int, trials: int, command: str
) -> None:
    """Write the study's page: headline, the table of every run, the figure."""
    lines = [
        "# The main job on real foam (hidden cells)", "",
        f"Generator seed {seed}, {trials} trials per run, run seed 0; command:", "",
        "```", command, "```", "",
        *headline(runs, trials), "",
        "Columns: k (N/mm), F_d (N), the foam's h, stiffening n and friction μ, the sensor's "
        "noise (N), the approach from the loading side the run used (mm; 0: direct), the "
        "trial of convergence (0: the first), ended in band, failed trials, the last 10 "
        "trials' mean force RMS in bands (5 % of F_d), the run's diagnosis.", "",
        "| cell | start | approach | k | F_d | h | n | μ | noise | approach mm | converged | "
        "in band | failed | end RMS / band | diagnosis |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|",
        *(_row(r) for r in sorted(runs, key=lambda r: (r.cell, r.start, r.approach))), "",
        f"![force RMS against trial, hysteretic cells]({figure.name})", "",
    ]
    page.parent.mkdir(parents=True, exist_ok=True)
    page.write_text("\n".join(lines), encoding="utf-8")


def write_figure(runs: Sequence[CellRun], figure: Path) -> None:
    """Force RMS (in bands) against trial of the hysteretic cells, one panel per approach."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    hyst = [r for r in runs if r.hysteretic and r.start == "probe"]
    approaches = sorted({r.approach for r in hyst}, key=lambda a: (a == "auto", a))
    if not approaches:
        return
    fig, axes = plt.subplots(1, len(approaches), figsize=(5.5 * len(approaches), 4),
                             sharey=True, squeeze=False)
    for ax, approach in zip(axes[0], approaches, strict=True):
        for r in sorted((r for r in hyst if r.approach == approach), key=lambda r: r.cell):
            ax.semilogy(range(len(r.force_rms_n)), [f / r.band_n for f in r.force_rms_n],
                        lw=0.9, label=f"{r.cell} h={r.hysteresis_loss:.2f}")
        ax.axhline(1.0, color="k", ls="--", lw=0.8)
        title = "after: approach 'auto'" if approach == "auto" else f"approach {approach!r}"
        ax.set_title(title)
        ax.set_xlabel("trial")
    axes[0][0].set_ylabel("force RMS / band (5 % of F_d)")
    for ax in axes[0]:
        ax.legend(fontsize=6, ncol=2)
    fig.tight_layout()
    figure.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(figure, dpi=110)
    plt.close(fig)
