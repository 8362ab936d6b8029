"""The members are refitted with the passes counted where the tool is only when it matters.

``fit.recounted_fits``: the passes counted again from the best member's surface; the members
are refitted from their own solutions when that count moves the best member's cost by more
than ``RECOUNT_COST``, and left as they are otherwise (a refit costs a whole fit's CPU).
"""

from __future__ import annotations

import dataclasses
from typing import Any

import numpy as np
import pytest

from forcelearn.emulators.physics.sponge import SpongeParams
from forcelearn.tools.twin import fit as fit_module
from forcelearn.tools.twin.arrays import RecordArrays, to_arrays
from forcelearn.tools.twin.fit import MemberFit, recounted_fits, split
from forcelearn.tools.twin.forward import Reading
from forcelearn.tools.twin.params import Member
from forcelearn.tools.twin.problem import Problem
from forcelearn.tools.twin.setup import base_arm
from forcelearn.tools.twin.simulate import DOWN, SimulatedRun, noise_only_sensor, simulate_run

ARM = base_arm()  # the emulator's defaults
READING = Reading.of(DOWN, 1, -1.0)
QUIET = noise_only_sensor(0.05)
MEMBER = Member("linear", ("surface_y_mm", "stiffness_n_per_mm"))


def _fits(cell: SpongeParams) -> tuple[RecordArrays, RecordArrays, list[MemberFit]]:
    """A short run of ``cell`` and one member "fitted" at the truth (its cost computed)."""
    records = simulate_run(SimulatedRun(trials=12, sponge=cell, sensor=QUIET), seed=5)
    train, heldout = split(to_arrays(records))
    values = {k: float(v) for k, v in dataclasses.asdict(cell).items()}
    problem = Problem(train, ARM, READING, 0.05)
    error = problem.residuals(problem.forward.predict(cell, READING))
    member = MemberFit(MEMBER, values, {n: 0.01 for n in MEMBER.free}, 0.0, 0.0, 0.0, 2,
                       train_cost=0.5 * float(error @ error))
    return train, heldout, [member]


def _recount(monkeypatch: pytest.MonkeyPatch, cell: SpongeParams, extra_passes: int
             ) -> tuple[RecordArrays, list[MemberFit], list[MemberFit], list[dict[str, Any]]]:
    """``recounted_fits`` with the surface's count ``extra_passes`` above the records'."""
    train, heldout, fits = _fits(cell)
    refits: list[dict[str, Any]] = []

    def counted(runs: list[RecordArrays], p: SpongeParams, arm: dict[str, float],
                apart: int | None = None) -> list[RecordArrays]:
        return [dataclasses.replace(r, passes=r.passes + extra_passes) for r in runs]

    def refit(member: Member, again: RecordArrays, *args: Any, **kwargs: Any) -> MemberFit:
        refits.append({"member": member, "passes": again.passes, "start": args[1]})
        return dataclasses.replace(fits[0], train_cost=-1.0, eligible=True)  # marks a refit

    monkeypatch.setattr(fit_module, "surface_passes", counted)
    monkeypatch.setattr(fit_module, "fit_member", refit)
    again, _, result = recounted_fits(fits, train, heldout, {}, ARM, READING, 0.05)
    return again, fits, result, refits


def test_a_count_that_moves_a_wearing_foams_cost_refits_every_member_from_its_own(
        monkeypatch: pytest.MonkeyPatch) -> None:
    """Forty passes more on a foam that softens and sets: refitted, on the new count."""
    cell = SpongeParams(relaxation_ratio=0.0, softening=0.3, softening_passes=30.0,
                        set_mm=2.0, set_passes=20.0)
    again, fits, result, refits = _recount(monkeypatch, cell, 40)
    assert [r["member"] for r in refits] == [MEMBER]
    assert refits[0]["start"] == fits[0].values  # from its own solution
    assert np.array_equal(refits[0]["passes"], again.passes)
    assert result[0].train_cost == -1.0 and result[0] is not fits[0]


def test_a_count_that_moves_no_cost_leaves_the_fits(monkeypatch: pytest.MonkeyPatch) -> None:
    """The same forty passes on a foam that never wears: the fits stand, the records' count."""
    cell = SpongeParams(relaxation_ratio=0.0, softening=0.0, set_mm=0.0)
    train, _, _ = _fits(cell)
    again, fits, result, refits = _recount(monkeypatch, cell, 40)
    assert refits == [] and result is fits
    assert np.array_equal(again.passes, train.passes)


def test_a_member_whose_cost_the_count_does_not_move_is_kept_not_refitted(
        monkeypatch: pytest.MonkeyPatch) -> None:
    """Forty passes more: the wearing member is refitted, one without wear only rescored."""
    cell = SpongeParams(relaxation_ratio=0.0, softening=0.3, softening_passes=30.0,
                        set_mm=2.0, set_passes=20.0)
    train, heldout, (wearing,) = _fits(cell)
    unworn = {**wearing.values, "softening": 0.0, "set_mm": 0.0}
    problem = Problem(train, ARM, READING, 0.05)
    error = problem.residuals(problem.forward.predict(SpongeParams.unchecked(unworn), READING))
    steady = dataclasses.replace(wearing, values=unworn, train_cost=0.5 * float(error @ error))
    refits: list[Member] = []

    def counted(runs: list[RecordArrays], p: SpongeParams, arm: dict[str, float],
                apart: int | None = None) -> list[RecordArrays]:
        return [dataclasses.replace(r, passes=r.passes + 40) for r in runs]

    def refit(member: Member, again: RecordArrays, *args: Any, **kwargs: Any) -> MemberFit:
        refits.append(member)
        return dataclasses.replace(wearing, train_cost=-1.0)  # marks a refit

    monkeypatch.setattr(fit_module, "surface_passes", counted)
    monkeypatch.setattr(fit_module, "fit_member", refit)
    _, _, result = recounted_fits([wearing, steady], train, heldout, {}, ARM, READING, 0.05)
    assert len(refits) == 1 and result[0].train_cost == -1.0  # the wearing member, refitted
    assert result[1].values == unworn  # kept where it was
    assert result[1].train_cost == pytest.approx(steady.train_cost, abs=1.0)
