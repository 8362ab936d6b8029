"""A run whose range is re-centred on the learner every trial resumes exactly (checkpoint)."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

import forcelearn.tasks.surface_map as surface_map
from forcelearn.tools.cli import main


def run(*args: str) -> None:
    """``forcelearn run`` in process; it must end normally."""
    assert main(["run", "--no-progress", *args]) == 0


def test_recentring_is_kept_across_a_resume(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A run split by a resume ends byte-identical to the whole run, re-centring included."""
    # re-centre on any drift, so every trial moves the range and its μ (the default share
    # of the half-range is never reached on the default cell)
    monkeypatch.setattr(surface_map, "RECENTRE_SHARE", 0.0)
    whole, split = tmp_path / "whole", tmp_path / "split"
    run("--seed", "2", "--trials", "4", "--out", str(whole))  # re-centred before and after
    run("--seed", "2", "--trials", "2", "--out", str(split))  # the split
    run("--resume", str(split), "--trials", "4")
    assert (whole / "trials.csv").read_bytes() == (split / "trials.csv").read_bytes()
    summary = json.loads((whole / "summary.json").read_text())
    assert summary["map_recentre_mm"] != 0.0
    assert json.loads((split / "summary.json").read_text())["map_recentre_mm"] == (
        summary["map_recentre_mm"]
    )
