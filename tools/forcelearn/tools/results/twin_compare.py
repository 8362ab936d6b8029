"""Compare a twin with its hidden cell's truth (the checks of docs/results/twin.md).

Pure functions over the files a study leaves: ``cell-XX.truth.json`` (the generator's
hidden truth), the twin's ``twin.json`` (``forcelearn twin``) and the run directories'
``summary.json`` and ``trials.csv`` (``forcelearn run``). No fitting happens here.
"""

from __future__ import annotations

import csv
import json
import math
import statistics
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from forcelearn.errors import StudyError

PREDICTION_NOISE_FACTOR = 2.0
"""The held-out force prediction's RMS must be at most this many times the sensor's noise."""
RELATIVE_TOLERANCE = 0.10
"""A determined parameter must lie within this share of the truth ..."""
LEARNING_TOLERANCE = 0.30
"""The twin's learning outcome must lie within this share of the hidden cell's."""
LATE_TRIALS = 10
"""Trials at a run's end whose mean force RMS is its late level (a second reading of "final
force RMS": one trial's RMS scatters ±30-50 % between seeds of one cell)."""


@dataclass(frozen=True)
class Checked:
    """One parameter the check covers: its twin.json name, where its truth is, its floor."""

    name: str
    label: str
    truth_path: tuple[str, str]
    absolute_bound: float
    """... or within this absolute bound (unit of the parameter), for values near 0."""


OPERATING_STIFFNESS = "stiffness_at_operating_point"
"""The derived check: the tangent stiffness where the desired force is met."""

CHECKED = (
    Checked(OPERATING_STIFFNESS, "stiffness at the operating point",
            ("sponge", "stiffness_n_per_mm"), 0.0),
    Checked("stiffness_n_per_mm", "stiffness (raw)", ("sponge", "stiffness_n_per_mm"), 0.0),
    Checked("surface_y_mm", "contact position", ("sponge", "surface_y_mm"), 0.3),
    Checked("softening", "softening", ("sponge", "softening"), 0.02),
    Checked("set_mm", "set", ("sponge", "set_mm"), 0.1),
    Checked("lag_s", "lag", ("arm", "lag_s"), 0.003),
    Checked("noise_std", "noise", ("sensor", "noise_n"), 0.01),
)
"""Stiffness, contact position, softening, set, lag and noise. The absolute
bounds are those of the fit's own "determined" test (docs/twin-fit.md) except the
contact position: 0.3 mm, a tenth of the drawn range's half-width (±3 mm). The stiffness
is judged at the cell's operating point (:func:`tangent_at_force`); the raw
``stiffness_n_per_mm`` (a stiffening foam's is its secant at the reference depth, a linear
member's its one slope: not the same quantity) is kept beside it."""

REFERENCE_DEPTH_MM = 10.0
"""The sponge's default ``stiffening_reference_mm`` (a twin.json without its sponge)."""


def tangent_at_force(stiffness: float, exponent: float, reference_mm: float,
                     force_n: float) -> float:
    """The foam's tangent stiffness dF/dd (N/mm) at the depth where it pushes ``force_n``.

    The fresh foam's law ``F = k d_ref (d / d_ref)^n`` (no wear, no variation along Z,
    relaxed): at ``d* = d_ref (F / (k d_ref))^(1/n)`` its slope is ``n F / d*``. For a
    linear foam (n = 1) it is ``k``. The tangent, not the secant ``F / d*``: a run holding
    its force in band moves in small steps about ``d*``, so the force change per mm there is
    what the learner meets and what its records measure.

    Raises:
        ValueError: a stiffness, exponent, reference depth or force that is not positive.
    """
    if min(stiffness, exponent, reference_mm, force_n) <= 0:
        raise ValueError("stiffness, exponent, reference depth and force must be positive, "
                         f"got {stiffness}, {exponent}, {reference_mm}, {force_n}")
    depth = reference_mm * (force_n / (stiffness * reference_mm)) ** (1.0 / exponent)
    return float(exponent * force_n / depth)


@dataclass(frozen=True)
class ParameterCheck:
    """One parameter of one twin against the truth."""

    name: str
    truth: float
    value: float | None
    determined: bool
    tolerance: float
    trials_to_determine: int | None

    @property
    def error(self) -> float | None:
        """Twin minus truth (the parameter's unit), or None when the twin lacks it."""
        return None if self.value is None else self.value - self.truth

    @property
    def within(self) -> bool:
        """The twin's value lies within the tolerance of the truth."""
        error = self.error
        return error is not None and abs(error) <= self.tolerance

    @property
    def verdict(self) -> str:
        """``within``, ``off`` (determined but outside the tolerance) or ``undetermined``."""
        if not self.determined:
            return "undetermined"
        return "within" if self.within else "off"


@dataclass(frozen=True)
class TwinCheck:
    """A twin against its hidden cell: represented or not, prediction, parameters."""

    cell: str
    represented: bool
    verdict: str
    heldout_rms_n: float
    noise_n: float
    parameters: tuple[ParameterCheck, ...]

    @property
    def prediction_ok(self) -> bool:
        """Held-out RMS at most 2x the true sensor noise."""
        return self.heldout_rms_n <= PREDICTION_NOISE_FACTOR * self.noise_n


def load_json(path: Path) -> dict[str, Any]:
    """A study file's JSON object (StudyError saying to rerun the study if it is unreadable)."""
    try:
        data = json.loads(path.read_text())
    except (OSError, json.JSONDecodeError) as exc:
        raise StudyError(f"cannot read {path}: {exc}; rerun the study to remake it") from exc
    if not isinstance(data, dict):
        raise StudyError(f"{path} does not hold a JSON object; rerun the study to remake it")
    return data


def check_twin(cell: str, truth_path: Path, twin_json: Path) -> TwinCheck:
    """Compare ``twin_json`` with the hidden truth in ``truth_path``.

    Raises:
        StudyError: a file is missing or is not what its writer writes.
    """
    truth = load_json(truth_path)
    twin = load_json(twin_json)
    try:
        rows = {row["name"]: row for row in twin["parameters"]}
        checks = [_operating_check(truth, twin, rows)]
        for checked in CHECKED[1:]:
            table, key = checked.truth_path
            true_value = float(truth[table][key])
            row = rows.get(checked.name)
            tolerance = max(RELATIVE_TOLERANCE * abs(true_value), checked.absolute_bound)
            checks.append(ParameterCheck(
                name=checked.name, truth=true_value,
                value=None if row is None else float(row["value"]),
                determined=bool(row and row["determined"]), tolerance=tolerance,
                trials_to_determine=None if row is None else row.get("trials_to_determine")))
        return TwinCheck(
            cell=cell, represented=bool(twin["represented"]), verdict=str(twin["verdict"]),
            heldout_rms_n=float(twin["residuals"]["heldout_rms_n"]),
            noise_n=float(truth["sensor"]["noise_n"]), parameters=tuple(checks))
    except (KeyError, TypeError, ValueError) as exc:
        raise StudyError(f"{twin_json} or {truth_path} lacks {exc}; "
                         "remake them with this version's generator and twin") from exc


def _operating_check(truth: dict[str, Any], twin: dict[str, Any],
                     rows: dict[str, Any]) -> ParameterCheck:
    """Truth and twin's tangent stiffness at the truth's desired force (fresh foam)."""
    force = float(truth["task"]["desired_force_n"])
    sponge = truth["sponge"]
    true_value = tangent_at_force(float(sponge["stiffness_n_per_mm"]),
                                  float(sponge.get("stiffening_exponent", 1.0)),
                                  float(sponge.get("stiffening_reference_mm", REFERENCE_DEPTH_MM)),
                                  force)
    stiffness = rows.get("stiffness_n_per_mm")
    exponent = rows.get("stiffening_exponent")
    fitted = twin.get("sponge", {})
    value = None
    if stiffness is not None:
        value = tangent_at_force(
            float(stiffness["value"]),
            float(exponent["value"]) if exponent is not None else 1.0,
            float(fitted.get("stiffening_reference_mm", REFERENCE_DEPTH_MM)), force)
    determined = bool(stiffness and stiffness["determined"]
                      and (exponent is None or exponent["determined"]))
    return ParameterCheck(
        name=OPERATING_STIFFNESS, truth=true_value, value=value, determined=determined,
        tolerance=RELATIVE_TOLERANCE * abs(true_value),
        trials_to_determine=None if stiffness is None else stiffness.get("trials_to_determine"))


@dataclass(frozen=True)
class RunOutcome:
    """One learning run: its trial of convergence (1-based; None: never) and final force RMS."""

    converged_trial: int | None
    final_force_rms_n: float
    late_force_rms_n: float = math.nan
    """Mean force RMS of the last ``LATE_TRIALS`` trials, N."""


def run_outcome(run_dir: Path) -> RunOutcome:
    """The outcome of a finished ``forcelearn run`` directory.

    The trial of convergence is ``summary.json``'s ``converged_trial`` counted from 1 (the
    first trial is trial 1); the final force RMS is the last trial's (``trials.csv``).

    Raises:
        StudyError: the run did not finish (no summary or no trials).
    """
    summary = load_json(run_dir / "summary.json")
    try:
        with (run_dir / "trials.csv").open(newline="") as handle:
            rows = list(csv.DictReader(handle))
        final = float(rows[-1]["force_rms_n"])
        late = statistics.fmean(float(row["force_rms_n"]) for row in rows[-LATE_TRIALS:])
    except (OSError, IndexError, KeyError, ValueError) as exc:
        raise StudyError(f"{run_dir} has no usable trials.csv ({exc}); rerun it") from exc
    index = summary.get("converged_trial") if summary.get("converged") else None
    return RunOutcome(None if index is None else int(index) + 1, final, late)


@dataclass(frozen=True)
class LearningSide:
    """Medians over seeds of one cell (hidden or twin)."""

    seeds: int
    median_converged_trial: float
    """A run that never converged counts as the trial budget + 1."""
    converged_runs: int
    median_final_force_rms_n: float
    median_late_force_rms_n: float = math.nan
    """Median over seeds of the mean force RMS of each run's last ``LATE_TRIALS`` trials, N."""


def learning_side(outcomes: Sequence[RunOutcome], budget: int) -> LearningSide:
    """Medians over the seeds' outcomes; a run that never converged counts as ``budget + 1``.

    Raises:
        ValueError: no outcomes.
    """
    if not outcomes:
        raise ValueError("no runs to summarise: run the seeds first")
    trials = [budget + 1 if o.converged_trial is None else o.converged_trial for o in outcomes]
    return LearningSide(
        seeds=len(outcomes), median_converged_trial=float(statistics.median(trials)),
        converged_runs=sum(o.converged_trial is not None for o in outcomes),
        median_final_force_rms_n=float(statistics.median(o.final_force_rms_n
                                                         for o in outcomes)),
        median_late_force_rms_n=float(statistics.median(o.late_force_rms_n
                                                        for o in outcomes)))


def relative_gap(twin: float, hidden: float) -> float:
    """(twin - hidden) / hidden; +inf when the hidden value is 0 and the twin's is not."""
    if hidden == 0:
        return 0.0 if twin == 0 else math.inf
    return (twin - hidden) / hidden


def learning_agrees(twin: LearningSide, hidden: LearningSide) -> tuple[bool, bool]:
    """Median trial of convergence and median final force RMS each within ±30 %."""
    return (abs(relative_gap(twin.median_converged_trial, hidden.median_converged_trial))
            <= LEARNING_TOLERANCE,
            abs(relative_gap(twin.median_final_force_rms_n, hidden.median_final_force_rms_n))
            <= LEARNING_TOLERANCE)


def late_agrees(twin: LearningSide, hidden: LearningSide) -> bool:
    """Median late force RMS (last ``LATE_TRIALS`` trials' mean) within ±30 %."""
    return (abs(relative_gap(twin.median_late_force_rms_n, hidden.median_late_force_rms_n))
            <= LEARNING_TOLERANCE)


def share(flags: Mapping[str, bool]) -> tuple[int, int]:
    """How many of ``flags`` are true, of how many."""
    return sum(flags.values()), len(flags)
