"""The path task end to end on the emulated cell (computer link + JR3), the tool turning."""

from __future__ import annotations

import csv
import json
from dataclasses import replace
from pathlib import Path

import pytest

from forcelearn.site import load_cell_config
from forcelearn.tools.experiments.path_run import run_path

EXAMPLE = Path(__file__).resolve().parents[2] / "examples" / "paths" / "cylinder-cell.toml"


def test_a_short_run_over_the_turning_cylinder_arc_writes_its_run_directory(
        tmp_path: Path) -> None:
    """Probe and 2 passes of 15 points (the tool turns 50 deg): records, summary, limits."""
    config = load_cell_config(EXAMPLE)
    assert config.path_task is not None
    config = replace(config, path_task=replace(config.path_task, points_per_pass=15),
                     emulator=replace(config.emulator, profile="ideal"))
    summary = run_path(config, tmp_path, passes=2, seed=0)
    assert summary["passes"] == 2 and summary["points"] == 15
    assert summary["moves_outside_workspace"] == 0
    assert summary["largest_offset_mm"] <= config.path_task.max_deviation_mm
    assert summary["probe_stiffness_n_per_mm"] > 0
    rows = list(csv.DictReader((tmp_path / "steps.csv").open()))
    assert len(rows) == 30 and {float(r["point"]) for r in rows} == set(map(float, range(15)))
    band = 0.1 * config.path_task.desired_force_n  # the probe's warm start: near the force
    assert all(abs(float(r["force_error_n"])) <= band for r in rows)
    assert json.loads((tmp_path / "summary.json").read_text())["task"] == "path"
    assert (tmp_path / "trials.csv").read_text().startswith("index,phase,steps")
    assert (tmp_path / "path_forces.png").stat().st_size > 0
    assert (tmp_path / "path_3d.png").stat().st_size > 0


def test_the_study_table_counts_what_each_run_reported(tmp_path: Path) -> None:
    """Two seeds of a part: one in band, one not, one run that failed with an error."""
    from forcelearn.tools.path_study import append, table

    base = {"cell": "link-jr3", "part": "gap", "passes": 20, "max_deviation_mm": 15.0,
            "moves_outside_workspace": 0, "error": ""}
    append(tmp_path / "results.csv", {**base, "seed": 0, "in_band_at_end": True,
                                      "warm_start_in_band_within_5": True,
                                      "final_force_rms_pct": 1.5, "largest_offset_mm": 9.0,
                                      "contact_lost_count": 40})
    append(tmp_path / "results.csv", {**base, "seed": 1, "in_band_at_end": False,
                                      "warm_start_in_band_within_5": True,
                                      "final_force_rms_pct": 2.5, "largest_offset_mm": 11.0,
                                      "contact_lost_count": 41})
    append(tmp_path / "results.csv", {**base, "seed": 2, "error": "LinkTimeout: gone"})
    row = table(tmp_path / "results.csv").splitlines()[-1]
    assert row == "| link-jr3 | gap | 3 | 1/3 | 2/3 | 2.00 (2.50) | 11.00 / 15.0 | 0 | 81 | 1 |"


def test_forcelearn_run_takes_the_path_task_from_the_option_or_the_config(
        tmp_path: Path) -> None:
    """``--path`` or ``[task] kind = "path"`` dispatch to the path run; the §5 run otherwise."""
    import argparse

    from forcelearn.tools.commands.run import add_arguments
    from forcelearn.tools.commands.run_path import is_path_run

    parser = argparse.ArgumentParser()
    add_arguments(parser)
    surface = tmp_path / "surface.toml"
    surface.write_text("[task]\ndesired_force_n = 19.6133\n")
    assert not is_path_run(parser.parse_args([]))
    assert not is_path_run(parser.parse_args(["--config", str(surface)]))
    assert is_path_run(parser.parse_args(["--config", str(surface), "--path", "arc.csv"]))
    assert is_path_run(parser.parse_args(["--config", str(EXAMPLE)]))


@pytest.mark.convergence
@pytest.mark.parametrize("part", ["cylinder", "sphere", "gap"])
def test_an_example_part_meets_the_acceptance_on_the_emulated_cell(
        part: str, tmp_path: Path) -> None:
    """docs/path.md's acceptance on one seed: in band at the end, from pass 0-4, RMS <= 3 %."""
    from forcelearn.tools.path_study import run_one

    row = run_one(part, "link-jr3", 1, 12, tmp_path)
    assert row["error"] == ""
    assert row["in_band_at_end"] and row["warm_start_in_band_within_5"]
    assert row["final_force_rms_pct"] <= 3.0
    assert row["largest_offset_mm"] <= row["max_deviation_mm"]
    assert row["moves_outside_workspace"] == 0
    assert (row["contact_lost_count"] > 0) == (part == "gap")
