"""The page and figure of the twin study (docs/results/twin.md): tables and summary figures.

Every figure on the page is computed here from the study's files; nothing is typed in.
"""

from __future__ import annotations

import json
import math
import textwrap
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from forcelearn.tools.results.twin_compare import (
    CHECKED,
    LATE_TRIALS,
    LEARNING_TOLERANCE,
    PREDICTION_NOISE_FACTOR,
    LearningSide,
    TwinCheck,
    late_agrees,
    learning_agrees,
    relative_gap,
)

TARGET_SHARE = 0.9


@dataclass(frozen=True)
class CellResult:
    """What the study knows of one hidden cell."""

    cell: str
    truth_path: Path
    site_rc: int | None
    check: TwinCheck | None
    hidden: LearningSide | None
    twin: LearningSide | None
    hidden_again: LearningSide | None = None
    """The hidden cell over the next seeds (``--self-check``): a perfect twin."""


def _truth_summary(path: Path) -> str:
    truth = json.loads(path.read_text())
    model = truth["model"]
    kinds = [name for name in ("nonlinear", "hysteresis", "friction") if model[name]]
    return ", ".join(kinds) or "linear"


def _pct(done: int, total: int) -> str:
    return f"{done}/{total} ({100 * done / total:.0f} %)" if total else "0/0"


def _met(done: int, total: int) -> str:
    if not total:
        return "(no cells to judge)"
    return "**met**" if done >= TARGET_SHARE * total else "**missed**"


def _gap(twin: float, hidden: float) -> str:
    gap = relative_gap(twin, hidden)
    return "inf" if math.isinf(gap) else f"{100 * gap:+.0f} %"


def _cell_rows(results: Sequence[CellResult]) -> list[str]:
    labels = [c.label for c in CHECKED]
    lines = ["| cell | foam | represented | held-out RMS N | 2x noise N | prediction | "
             + " | ".join(labels) + " |",
             "|---|---|---|---|---|---|" + "---|" * len(labels)]
    for result in results:
        check = result.check
        if check is None:
            state = "run failed" if result.site_rc not in (None, 0) else "not run"
            lines.append(f"| {result.cell[-2:]} | {_truth_summary(result.truth_path)} | "
                         f"{state} | | | |" + " |" * len(labels))
            continue
        params = []
        for param in check.parameters:
            if param.value is None:
                params.append("absent")
                continue
            rel = (f"{100 * param.error / param.truth:+.1f} %" if param.truth
                   and param.error is not None else f"{param.error:+.3g}")
            mark = {"within": "", "off": " ✗", "undetermined": " (undet.)"}[param.verdict]
            if param.verdict == "undetermined" and param.trials_to_determine is not None:
                mark = f" (undet.; {param.trials_to_determine} trials)"
            params.append(f"{param.value:.3g} vs {param.truth:.3g} ({rel}){mark}")
        lines.append(
            f"| {result.cell[-2:]} | {_truth_summary(result.truth_path)} | "
            f"{'yes' if check.represented else 'no'} | {check.heldout_rms_n:.3f} | "
            f"{PREDICTION_NOISE_FACTOR * check.noise_n:.3f} | "
            f"{'ok' if check.prediction_ok else 'over'} | " + " | ".join(params) + " |")
    return lines


def _learning_rows(results: Sequence[CellResult]) -> list[str]:
    lines = ["| cell | hidden: median conv. trial (converged runs) | twin: same | gap | "
             "hidden: median final RMS N | twin: same | gap | both within ±30 % | "
             f"hidden: median RMS of the last {LATE_TRIALS} trials N | twin: same | gap |",
             "|---|---|---|---|---|---|---|---|---|---|---|"]
    for result in results:
        hidden, twin = result.hidden, result.twin
        if hidden is None or twin is None:
            continue
        trial_ok, rms_ok = learning_agrees(twin, hidden)
        lines.append(
            f"| {result.cell[-2:]} | {hidden.median_converged_trial:g} "
            f"({hidden.converged_runs}/{hidden.seeds}) | {twin.median_converged_trial:g} "
            f"({twin.converged_runs}/{twin.seeds}) | "
            f"{_gap(twin.median_converged_trial, hidden.median_converged_trial)} | "
            f"{hidden.median_final_force_rms_n:.3f} | {twin.median_final_force_rms_n:.3f} | "
            f"{_gap(twin.median_final_force_rms_n, hidden.median_final_force_rms_n)} | "
            f"{'yes' if trial_ok and rms_ok else 'no'} | "
            f"{hidden.median_late_force_rms_n:.3f} | {twin.median_late_force_rms_n:.3f} | "
            f"{_gap(twin.median_late_force_rms_n, hidden.median_late_force_rms_n)} |")
    return lines


def _agreement(pairs: Sequence[tuple[LearningSide, LearningSide]]) -> str:
    """Counts of the ±30 % checks over (candidate, hidden) pairs."""
    flags = [(*learning_agrees(a, b), late_agrees(a, b)) for a, b in pairs]
    n = len(flags)
    return (f"median trial of convergence {_pct(sum(f[0] for f in flags), n)}, median final "
            f"force RMS {_pct(sum(f[1] for f in flags), n)}, both "
            f"{_pct(sum(f[0] and f[1] for f in flags), n)}; median RMS of the last "
            f"{LATE_TRIALS} trials {_pct(sum(f[2] for f in flags), n)}, with the trial "
            f"{_pct(sum(f[0] and f[2] for f in flags), n)}")


def self_check_lines(results: Sequence[CellResult], seeds: int) -> list[str]:
    """The hidden cell against itself over other seeds: the best a twin could agree."""
    pairs = [(r.hidden_again, r.hidden) for r in results if r.hidden_again and r.hidden]
    if not pairs:
        return ["- not run (`--self-check EVERY`)"]
    lines = [f"- {len(pairs)} cells, seeds {seeds}-{2 * seeds - 1} against seeds 0-{seeds - 1} "
             f"of the same hidden cell: {_agreement(pairs)}.", "",
             "| cell | conv. trial, seeds 0-4 | seeds 5-9 | final RMS N, seeds 0-4 | "
             "seeds 5-9 | last-10 RMS N, seeds 0-4 | seeds 5-9 |",
             "|---|---|---|---|---|---|---|"]
    for result in results:
        again, hidden = result.hidden_again, result.hidden
        if again is None or hidden is None:
            continue
        lines.append(
            f"| {result.cell[-2:]} | {hidden.median_converged_trial:g} | "
            f"{again.median_converged_trial:g} | {hidden.median_final_force_rms_n:.3f} | "
            f"{again.median_final_force_rms_n:.3f} | {hidden.median_late_force_rms_n:.3f} | "
            f"{again.median_late_force_rms_n:.3f} |")
    return lines


def summary_lines(results: Sequence[CellResult], seeds: int) -> list[str]:
    """The summary figures against the twin's targets (docs/twin.md)."""
    checked = [r.check for r in results if r.check is not None]
    twins = [c for c in checked if c.represented]
    lines = [f"- Cells: {len(results)} drawn, {len(checked)} fitted, "
             f"{len(twins)} declared represented (a twin.toml written), "
             f"{len(checked) - len(twins)} declared not represented."]
    ok_all = sum(c.prediction_ok for c in checked)
    ok_twins = sum(c.prediction_ok for c in twins)
    lines.append(
        f"- Open-loop prediction on the held-out trials, RMS ≤ 2x the true sensor noise "
        f"(target ≥ 90 % of the cells): all fitted cells {_pct(ok_all, len(checked))} "
        f"{_met(ok_all, len(checked))}; the represented cells "
        f"{_pct(ok_twins, len(twins))} {_met(ok_twins, len(twins))}.")
    for index, param in enumerate(CHECKED):
        rows = [c.parameters[index] for c in twins]
        determined = [p for p in rows if p.determined]
        within = sum(p.within for p in determined)
        lines.append(
            f"- {param.label} (within 10 % or {param.absolute_bound:g}, on the represented "
            f"cells where determined): {_pct(within, len(determined))} "
            f"{_met(within, len(determined))}; undetermined on {len(rows) - len(determined)} "
            f"of {len(rows)}.")
    pairs = [(r.twin, r.hidden) for r in results if r.twin and r.hidden]
    lines.append(
        f"- Learning outcome over {seeds} seeds (target: within ±30 %; measured on "
        f"{len(pairs)} cells): {_agreement(pairs)}.")
    return lines


def unrepresented_lines(results: Sequence[CellResult]) -> list[str]:
    """Each cell the fit declared not represented, with the fit's reason."""
    lines = []
    for result in results:
        if result.check is not None and not result.check.represented:
            lines.append(f"- {result.cell} ({_truth_summary(result.truth_path)}): "
                         f"{result.check.verdict}")
    return lines or ["- none"]


def write_page(results: Sequence[CellResult], page: Path, figure: Path, *,
               generator_seed: int, seeds: int, trials: int, workers: int = 2,
               identify: bool = False, run_seed: str = "cell", shaped: float = 0.0) -> None:
    """Write the Markdown page of the study.

    ``run_seed``: the study's ``--run-seed`` (``cell`` or ``zero``); ``shaped``: its
    ``--shaped`` share (cells whose strip has periodic shapes of its own).
    """
    site_seed = "R" if run_seed == "cell" else "0"
    twin_line = ("#           forcelearn twin DIR/cell-XX/site --out DIR/cell-XX/twin/twin.toml "
                 "--no-figure")
    identify_lines = []
    if identify:
        identify_seed = "R+100000" if run_seed == "cell" else "0"
        identify_lines = [f"#           forcelearn identify --config cell-XX.toml --seed "
                          f"{identify_seed} --out DIR/cell-XX/identify   (every cell's first)"]
        twin_line = twin_line.replace("site --out", "site --identification DIR/cell-XX/identify "
                                                    "--out")
    lines = [
        "# The twin against hidden cells",
        "",
        "Made by (generator seed, commands):",
        "",
        "```",
        f"python -m forcelearn.tools.results.twin --cells {len(results)} "
        f"--seed {generator_seed} --out DIR --workers {workers} --seeds {seeds}"
        + (" --identify" if identify else "") + f" --run-seed {run_seed}"
        + (f" --shaped {shaped:g}" if shaped > 0 else ""),
        *identify_lines,
        "# per cell: forcelearn run --config cell-XX.toml --trials "
        f"{trials} --seed {site_seed} --out DIR/cell-XX/site"
        + ("   (R = 1000 x generator seed + cell number)" if run_seed == "cell" else
           "   (every cell's sensor walks alike)"),
        twin_line,
        f"#           forcelearn run --config {{cell-XX.toml, twin.toml}} --trials {trials} "
        "--seed S   (S = 0..seeds-1)",
        "```",
        "",
        f"![the twin against the hidden cells]({figure.name})",
        "",
        "## Summary against the targets",
        "",
        *summary_lines(results, seeds),
        "",
        "## Cells declared not represented, and why",
        "",
        *unrepresented_lines(results),
        "",
        "## Per cell: prediction and parameters",
        "",
        "Parameters: twin vs truth (twin's error); ✗ determined by the fit but outside the "
        "tolerance; (undet.; n trials) the fit says the records do not determine it, and "
        "how many trials would (twin.json gives its uncertainty).",
        "",
        "Stiffness at the operating point: truth and twin each give the tangent stiffness "
        "dF/dd of the fresh foam (no wear, mean along Z) at the depth where it pushes the "
        "cell's desired force, n F / d* with d* = d_ref (F / (k d_ref))^(1/n) (n = 1 for a "
        "linear member: its k). The tangent, not the secant F / d*: a run holding its force "
        "in band steps about d*, so the force change per mm there is what the learner meets "
        "and what its records measure. A stiffening foam's raw `stiffness_n_per_mm` is its "
        "secant at the 10 mm reference depth, not the same quantity as a linear member's "
        "slope; the raw values are kept as their own column. Contact position: within "
        "0.3 mm (the depth error that moves the force by the sensor's noise, noise / "
        "tangent stiffness, is 0.015-0.9 mm over these cells, median 0.27 mm: no single "
        "physical bound, so the stated 0.3 mm stays).",
        "",
        *_cell_rows(results),
        "",
        f"## Per cell: the learning outcome over {seeds} seeds",
        "",
        f"A run that never converged counts as trial {trials + 1}; trials are counted from "
        f"1. Agreement: within ±{100 * LEARNING_TOLERANCE:.0f} % of the hidden cell's.",
        "",
        *_learning_rows(results),
        "",
        "## The hidden cell against itself: how well a perfect twin could agree",
        "",
        "The same checks between two sets of seeds on the same hidden cell: the scatter of "
        "the learner's seeds alone, with no model error. A twin cannot be expected to agree "
        "more often than this.",
        "",
        *self_check_lines(results, seeds),
        "",
    ]
    page.parent.mkdir(parents=True, exist_ok=True)
    page.write_text("\n".join(lines))


def write_figure(results: Sequence[CellResult], path: Path) -> None:
    """Three panels: held-out RMS over noise, parameter errors, learning outcome twin vs hidden."""
    fig = Figure(figsize=(15, 4.8))
    FigureCanvasAgg(fig)
    left, middle, right = fig.subplots(1, 3)
    checked = [r for r in results if r.check is not None]
    for index, result in enumerate(checked):
        assert result.check is not None
        check = result.check
        colour = "tab:blue" if check.represented else "tab:red"
        left.bar(index, check.heldout_rms_n / check.noise_n, color=colour)
    left.axhline(PREDICTION_NOISE_FACTOR, color="black", linestyle="--", label="target: 2x")
    left.set_xticks(range(len(checked)), [r.cell[-2:] for r in checked], fontsize=7,
                  rotation=90)
    left.set_yscale("log")
    left.set_xlabel("hidden cell (red: declared not represented)")
    left.set_ylabel("held-out RMS / true sensor noise")
    left.set_title("open-loop prediction, held-out trials")
    left.legend()
    for index in range(len(CHECKED)):
        for result in checked:
            assert result.check is not None
            if not result.check.represented:
                continue
            row = result.check.parameters[index]
            if row.error is None:
                continue
            middle.scatter(index, row.error / row.tolerance, s=18,
                           color="tab:green" if row.determined else "lightgray",
                           edgecolor="black" if row.determined and not row.within else "none")
    middle.axhspan(-1, 1, color="tab:green", alpha=0.1)
    middle.set_xticks(range(len(CHECKED)), [textwrap.fill(p.label, 12) for p in CHECKED],
                      fontsize=8)
    middle.set_yscale("symlog", linthresh=1)
    middle.set_ylabel("(twin - truth) / tolerance (band: within)")
    middle.set_title("parameters (green: determined; grey: not)")
    learned = [r for r in results if r.twin and r.hidden]
    for index, result in enumerate(learned):
        assert result.twin is not None and result.hidden is not None
        trial = relative_gap(result.twin.median_converged_trial,
                             result.hidden.median_converged_trial)
        rms = relative_gap(result.twin.median_final_force_rms_n,
                           result.hidden.median_final_force_rms_n)
        right.scatter(index - 0.1, 100 * min(trial, 3.0), color="tab:orange", marker="o",
                      label="median trial of convergence" if index == 0 else None)
        right.scatter(index + 0.1, 100 * min(rms, 3.0), color="tab:purple", marker="s",
                      label="median final force RMS" if index == 0 else None)
    right.axhspan(-100 * LEARNING_TOLERANCE, 100 * LEARNING_TOLERANCE, color="tab:green",
                  alpha=0.1)
    right.set_xticks(range(len(learned)), [r.cell[-2:] for r in learned], fontsize=7,
                     rotation=90)
    right.set_xlabel("hidden cell")
    right.set_ylabel("twin vs hidden cell, % (band: ±30 %; capped at +300 %)")
    if learned:
        right.legend(fontsize=8)
    pairs = learned
    right.set_title(f"learning outcome ({len(pairs)} cells)")
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
