"""Each hidden cell's site and identification runs draw their own sensor noise and walk."""

from __future__ import annotations

from pathlib import Path

import pytest

from forcelearn.tools.results import twin as study


def _commands(monkeypatch: pytest.MonkeyPatch) -> list[list[str]]:
    ran: list[list[str]] = []

    def step(rc_file: Path, command: list[str], log: Path) -> int:
        ran.append(command)
        return 0

    monkeypatch.setattr(study, "_step", step)
    return ran


def _seed_of(command: list[str]) -> str:
    return command[command.index("--seed") + 1]


def test_cells_get_their_own_run_and_identification_seeds(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """Two cells of one study, and one cell of two studies: every seed differs."""
    ran = _commands(monkeypatch)
    seeds = [study.run_seed(g, c) for g, c in ((6, "cell-01"), (6, "cell-02"), (7, "cell-01"))]
    for seed in seeds:
        study.site_and_twin(tmp_path, "cell-01", identify=True, fit=False, seed=seed)
    identify = [_seed_of(c) for c in ran if "identify" in c]
    site = [_seed_of(c) for c in ran if "run" in c]
    assert len(set(identify + site)) == 6
    assert site == [str(s) for s in seeds]


def test_the_shared_seed_of_older_studies_is_kept(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """--run-seed zero: seed 0 for the site run and the identification, as drawn before."""
    ran = _commands(monkeypatch)
    study.site_and_twin(tmp_path, "cell-05", identify=True, fit=False, seed=0)
    assert [_seed_of(c) for c in ran] == ["0", "0"]
