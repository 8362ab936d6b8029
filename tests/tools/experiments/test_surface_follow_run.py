"""``forcelearn run`` on a stiff sponge at a small force: the map follows surface and wear."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import pytest

from forcelearn.tools.cli import main

STIFF_SMALL_FORCE = (
    "[task]\ndesired_force_n = 4.903325\n[emulator.sponge]\nstiffness_n_per_mm = 4.0\n"
)
"""0.5 kgf on a sponge twice as stiff: a ±0.6 mm band, where a constant centre cannot work."""
TRIALS = 4
STEP_Z_MM = {round(-5.0 * step, 6) for step in range(1, 21)}
"""The task's 20 steps' Z (5 mm down per step from Z = 0)."""


def _assert_dense_probe(fits: list[dict[str, float]]) -> None:
    """3 points, 4 more to follow the surface, then the steps' Z where the grid misses the waves.

    At ±0.6 mm of band the grid's interpolation misses more than 2 bands, so the
    probe adds points at the steps' Z (and re-reads its first point for its own wear).
    """
    grid = [round(f["z_mm"], 6) for f in fits[:7]]
    extra = [round(f["z_mm"], 6) for f in fits[7:]]
    assert len(set(grid)) == 7 and extra, [f["z_mm"] for f in fits]
    assert set(extra) <= STEP_Z_MM | {grid[0]}, extra


def _run(tmp_path: Path, name: str, *args: str) -> Path:
    config = tmp_path / "cell.toml"
    config.write_text(STIFF_SMALL_FORCE)
    out = tmp_path / name
    assert main(["run", "--config", str(config), "--out", str(out), "--no-progress", *args]) == 0
    return out


@pytest.fixture(scope="module")
def straight(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """An uninterrupted short run on the stiff sponge."""
    return _run(tmp_path_factory.mktemp("follow"), "straight", "--trials", str(TRIALS))


def test_each_trial_presses_in_at_the_desired_force_and_the_map_moves_with_it(
    straight: Path,
) -> None:
    """The start press lands within the band (start_mm's Y would press ~27 N) and is tracked."""
    summary = json.loads((straight / "summary.json").read_text())
    choice = summary["output_map"]
    assert len(choice["path_y_mm"]) == 20 and choice["start_press_y_mm"] is not None
    assert choice["wear_stiffness_n_per_mm"] == pytest.approx(
        summary["probe_stiffness_n_per_mm"]
    )
    _assert_dense_probe(summary["probe_fits"])
    rows = list(csv.DictReader((straight / "trials.csv").open()))
    desired, band = summary["desired_force_n"], 0.5 * summary["desired_force_n"]
    starts = [float(r["start_force_n"]) for r in rows]
    assert all(abs(f - desired) < band for f in starts), starts
    assert summary["map_shift_mm"] != 0.0  # the start forces' errors moved the map


def test_a_resumed_run_goes_on_from_the_same_shifted_map(straight: Path, tmp_path: Path) -> None:
    """Half the trials, then --resume: the trials equal the straight run's (the shift is saved)."""
    out = _run(tmp_path, "resumed", "--trials", str(TRIALS // 2))
    assert main(["run", "--resume", str(out), "--trials", str(TRIALS), "--no-progress"]) == 0
    assert (out / "trials.csv").read_text() == (straight / "trials.csv").read_text()
    a = json.loads((straight / "summary.json").read_text())
    b = json.loads((out / "summary.json").read_text())
    assert b["map_shift_mm"] == a["map_shift_mm"]


def test_forcelearn_probe_chooses_the_map_the_run_uses(straight: Path, tmp_path: Path) -> None:
    """``forcelearn probe`` refines and follows as the run does: the same fits and map."""
    config = tmp_path / "cell.toml"
    config.write_text(STIFF_SMALL_FORCE)
    out = tmp_path / "probe"
    assert main(["probe", "--config", str(config), "--out", str(out), "--seed", "0"]) == 0
    probed = json.loads((out / "probe.json").read_text())
    summary = json.loads((straight / "summary.json").read_text())
    assert probed["output_map"] == summary["output_map"]
    assert len(probed["fits"]) == len(summary["probe_fits"])
    _assert_dense_probe(probed["fits"])
