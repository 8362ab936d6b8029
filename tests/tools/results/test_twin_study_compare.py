"""The twin study's comparison with the hidden truth, on a fake cell (no run, no fit)."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from forcelearn.errors import StudyError
from forcelearn.tools.results.twin_compare import (
    LATE_TRIALS,
    RunOutcome,
    check_twin,
    late_agrees,
    learning_agrees,
    learning_side,
    run_outcome,
)
from forcelearn.tools.results.twin_page import CellResult, self_check_lines, summary_lines

TRUTH = {
    "sponge": {"stiffness_n_per_mm": 2.0, "surface_y_mm": 0.1, "softening": 0.3,
               "set_mm": 0.05},
    "arm": {"lag_s": 0.05},
    "sensor": {"noise_n": 0.2},
    "model": {"nonlinear": False, "hysteresis": False, "friction": False},
    "task": {"desired_force_n": 10.0},
}


def _row(name: str, value: float, determined: bool = True) -> dict[str, object]:
    return {"name": name, "value": value, "determined": determined,
            "trials_to_determine": None if determined else 400}


def _write_cell(tmp_path: Path, heldout_rms: float, rows: list[dict[str, object]],
                represented: bool = True) -> tuple[Path, Path]:
    truth = tmp_path / "cell-01.truth.json"
    truth.write_text(json.dumps(TRUTH))
    twin = tmp_path / "twin.json"
    twin.write_text(json.dumps({"represented": represented, "verdict": "because",
                                "parameters": rows,
                                "residuals": {"heldout_rms_n": heldout_rms}}))
    return truth, twin


def test_parameters_judged_only_where_determined(tmp_path: Path) -> None:
    """A parameter counts within/off only where the fit says it is determined."""
    truth, twin = _write_cell(tmp_path, 0.39, [
        _row("stiffness_n_per_mm", 2.19),          # +9.5 %: within
        _row("surface_y_mm", 0.35),                # 0.25 mm off a 0.1 mm truth: absolute bound
        _row("softening", 0.2, determined=False),  # far off, but undetermined
        _row("set_mm", 0.2),                       # 0.15 mm off: beyond 0.1 mm
        _row("lag_s", 0.044),                      # -12 %: off
        _row("noise_std", 0.205),
    ])
    check = check_twin("cell-01", truth, twin)
    verdicts = {p.name: p.verdict for p in check.parameters}
    assert verdicts == {"stiffness_at_operating_point": "within", "stiffness_n_per_mm": "within",
                        "surface_y_mm": "within",
                        "softening": "undetermined", "set_mm": "off", "lag_s": "off",
                        "noise_std": "within"}
    assert check.prediction_ok  # 0.39 <= 2 x 0.2
    _, over = _write_cell(tmp_path, 0.41, [])
    with_missing = check_twin("cell-01", truth, over)
    assert not with_missing.prediction_ok
    assert all(p.verdict == "undetermined" and p.value is None
               for p in with_missing.parameters)


def test_damaged_twin_json_is_a_study_error(tmp_path: Path) -> None:
    """A corrupt or incomplete twin.json is a StudyError naming the remedy."""
    truth, twin = _write_cell(tmp_path, 0.1, [])
    twin.write_text("{not json")
    with pytest.raises(StudyError, match="rerun"):
        check_twin("cell-01", truth, twin)
    twin.write_text(json.dumps({"represented": True}))
    with pytest.raises(StudyError, match="lacks"):
        check_twin("cell-01", truth, twin)


def _run(folder: Path, converged: int | None, rms: list[float]) -> Path:
    folder.mkdir()
    (folder / "summary.json").write_text(json.dumps(
        {"converged": converged is not None, "converged_trial": converged}))
    lines = ["index,force_rms_n"] + [f"{i},{value}" for i, value in enumerate(rms)]
    (folder / "trials.csv").write_text("\n".join(lines) + "\n")
    return folder


def test_run_outcome_counts_from_one_and_takes_the_last_trial(tmp_path: Path) -> None:
    """Convergence trial counted from 1; final RMS is the last trial's."""
    assert run_outcome(_run(tmp_path / "a", 0, [3.0, 0.4])) == RunOutcome(1, 0.4, 1.7)
    assert run_outcome(_run(tmp_path / "b", None, [3.0, 1.5])) == RunOutcome(None, 1.5, 2.25)
    with pytest.raises(StudyError):
        run_outcome(tmp_path / "missing")


def test_the_late_level_is_the_mean_of_the_last_trials(tmp_path: Path) -> None:
    """The late force RMS averages the last LATE_TRIALS trials, not the run's first ones."""
    rms = [5.0] * 5 + [0.2, 0.4] * (LATE_TRIALS // 2)
    outcome = run_outcome(_run(tmp_path / "a", 3, rms))
    assert outcome.final_force_rms_n == 0.4
    assert outcome.late_force_rms_n == pytest.approx(0.3)
    side = learning_side([outcome, RunOutcome(4, 0.2, 0.32), RunOutcome(5, 0.9, 0.5)], 60)
    assert side.median_late_force_rms_n == pytest.approx(0.32)
    other = learning_side([RunOutcome(4, 0.2, 0.45)] * 3, 60)
    assert not late_agrees(other, side)  # +41 %
    assert late_agrees(learning_side([RunOutcome(4, 0.2, 0.4)] * 3, 60), side)  # +25 %


def test_the_self_check_compares_a_cell_with_itself(tmp_path: Path) -> None:
    """Seeds 5-9 against 0-4 of one hidden cell: counted with the twin's checks."""
    hidden = learning_side([RunOutcome(10, 0.5, 0.5)] * 5, 60)
    again = learning_side([RunOutcome(12, 0.9, 0.55)] * 5, 60)
    result = CellResult("cell-03", tmp_path / "t.json", 0, None, None, None, again)
    assert self_check_lines([result], 5) == ["- not run (`--self-check EVERY`)"]
    result = CellResult("cell-03", tmp_path / "t.json", 0, None, hidden, None, again)
    lines = self_check_lines([result], 5)
    assert "median trial of convergence 1/1 (100 %)" in lines[0]
    assert "median final force RMS 0/1 (0 %)" in lines[0]  # +80 %
    assert "last 10 trials 1/1 (100 %)" in lines[0]
    assert lines[-1].startswith("| 03 | 10 | 12 |")


def test_learning_medians_and_agreement() -> None:
    """Medians over seeds (never converged = budget + 1) and the ±30 % test."""
    hidden = learning_side([RunOutcome(10, 0.5), RunOutcome(None, 0.6), RunOutcome(12, 0.4)],
                           budget=60)
    assert hidden.median_converged_trial == 12 and hidden.converged_runs == 2
    assert hidden.median_final_force_rms_n == 0.5
    close = learning_side([RunOutcome(14, 0.6), RunOutcome(15, 0.6), RunOutcome(9, 0.3)], 60)
    assert learning_agrees(close, hidden) == (True, True)  # +25 %, +20 %
    never = learning_side([RunOutcome(None, 0.5)] * 3, 60)
    assert never.median_converged_trial == 61
    assert learning_agrees(never, hidden) == (False, True)
    with pytest.raises(ValueError):
        learning_side([], 60)


def test_summary_counts_against_the_targets(tmp_path: Path) -> None:
    """The page's summary counts the cells against the 90 % target."""
    truth, twin = _write_cell(tmp_path, 0.39, [_row("stiffness_n_per_mm", 2.5)])
    check = check_twin("cell-01", truth, twin)
    result = CellResult("cell-01", truth, 0, check, None, None)
    text = "\n".join(summary_lines([result], seeds=5))
    assert "1/1 (100 %) **met**" in text  # the prediction
    assert "stiffness at the operating point (within 10 % or 0, on the represented cells " \
           "where determined): 0/1 (0 %) **missed**" in text


def test_stiffening_foam_is_compared_at_the_operating_point(tmp_path: Path) -> None:
    """A stiffening foam's raw stiffness (secant at 10 mm) is not a linear twin's k.

    Truth: n = 1.5, k = 2 N/mm at 10 mm; the desired 10 N is met at d* = 6.30 mm, where
    the tangent is 1.5 x 10 / 6.30 = 2.38 N/mm. A linear twin with k = 2.38 is right there
    (raw: +19 %, off); one with k = 2.0 (raw: equal) is 16 % too soft where the run works.
    """
    truth_data = {**TRUTH, "sponge": {"stiffness_n_per_mm": 2.0, "surface_y_mm": 0.1,
                                       "softening": 0.3, "set_mm": 0.05,
                                       "stiffening_exponent": 1.5,
                                       "stiffening_reference_mm": 10.0}}
    truth = tmp_path / "cell-01.truth.json"
    truth.write_text(json.dumps(truth_data))
    expected = 1.5 * 10.0 / (10.0 * (10.0 / 20.0) ** (1 / 1.5))
    for k, operating, raw in ((expected, "within", "off"), (2.0, "off", "within")):
        twin = tmp_path / f"twin-{k}.json"
        twin.write_text(json.dumps({"represented": True, "verdict": "because",
                                    "parameters": [_row("stiffness_n_per_mm", k)],
                                    "residuals": {"heldout_rms_n": 0.1}}))
        verdicts = {p.name: p.verdict for p in check_twin("cell-01", truth, twin).parameters}
        assert (verdicts["stiffness_at_operating_point"], verdicts["stiffness_n_per_mm"]) == \
            (operating, raw)
    # a nonlinear twin equal to the truth is within on both; its exponent must be determined
    same = tmp_path / "twin-same.json"
    rows = [_row("stiffness_n_per_mm", 2.0), _row("stiffening_exponent", 1.5)]
    same.write_text(json.dumps({"represented": True, "verdict": "because", "parameters": rows,
                                "residuals": {"heldout_rms_n": 0.1}}))
    check = check_twin("cell-01", truth, same).parameters[0]
    assert check.verdict == "within" and check.value == pytest.approx(expected)
    rows[1]["determined"] = False
    same.write_text(json.dumps({"represented": True, "verdict": "because", "parameters": rows,
                                "residuals": {"heldout_rms_n": 0.1}}))
    assert check_twin("cell-01", truth, same).parameters[0].verdict == "undetermined"
