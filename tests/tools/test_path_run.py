"""The path task end to end on the emulated cell (computer link + JR3), the tool turning."""

from __future__ import annotations

import csv
from pathlib import Path

import pytest

from forcelearn.site import load_cell_config
from forcelearn.tools.experiments.path_run import load_path

EXAMPLE = Path(__file__).resolve().parents[2] / "examples" / "paths" / "cylinder-cell.toml"


def short_config(tmp_path: Path, extra: str = "") -> Path:
    """The cylinder example as a config file of 6 points a pass on the ideal emulated cell."""
    text = EXAMPLE.read_text()
    for name in ("cylinder-arc.csv", "emulated-jr3-cal.toml"):
        text = text.replace(f'"{name}"', f'"{EXAMPLE.parent / name}"')
    text = text.replace('kind = "path"', 'kind = "path"\npoints_per_pass = 6\nmax_turn_deg = 12.0')
    text = text.replace("max_step_mm = 10.0", "max_step_mm = 30.0")  # 26 mm between points
    file = tmp_path / "cell.toml"
    file.write_text(text + '\n[emulator]\nprofile = "ideal"\n' + extra)
    return file


class Stop(KeyboardInterrupt):
    """Ctrl-C after a pass (the test's kill)."""


def test_a_killed_run_resumes_at_the_next_pass_as_if_never_stopped(tmp_path: Path) -> None:
    """Kill after pass 1 of 3, resume: trials, passes and steps as an uninterrupted run's."""
    from forcelearn.tools.experiments.path_run import execute
    from forcelearn.tools.experiments.path_state import prepare_path_run
    from forcelearn.tools.experiments.records import read_records

    config = short_config(tmp_path)
    whole, _ = prepare_path_run(config, None, tmp_path / "whole", 3, 0, 25, resume=False)
    summary = execute(whole, None)
    assert summary["passes"] == 3 and summary["points"] == 6
    assert summary["moves_outside_workspace"] == 0 and summary["faults"]["count"] == 0
    assert summary["largest_offset_mm"] <= 15.0 and summary["probe_stiffness_n_per_mm"] > 0
    band = 0.1 * 19.6133  # the probe's warm start: near the force
    rows = list(csv.DictReader((tmp_path / "whole" / "steps.csv").open()))
    assert len(rows) == 18 and all(abs(float(r["force_error_n"])) <= band for r in rows)
    assert all(0 <= float(r["tangential_force_n"]) < band for r in rows)
    assert [t.trial for t in read_records(tmp_path / "whole", probe=True)] == [-1, 0, 1, 2]
    assert (tmp_path / "whole" / "path_3d.png").stat().st_size > 0

    def kill(record: object, learner: object) -> None:
        raise Stop

    killed, _ = prepare_path_run(config, None, tmp_path / "killed", 3, 0, 25, resume=False)
    with pytest.raises(Stop):
        execute(killed, None, on_pass=kill, figures=False)
    assert len((tmp_path / "killed" / "trials.csv").read_text().splitlines()) == 2
    resumed, state = prepare_path_run(None, None, tmp_path / "killed", None, None, 25,
                                      resume=True)
    assert state is not None and resumed.trials == 3
    execute(resumed, state, figures=False)
    for name in ("trials.csv", "passes.csv", "steps.csv", "probe.csv"):
        assert (tmp_path / "killed" / name).read_bytes() == \
            (tmp_path / "whole" / name).read_bytes(), name
    assert [t.trial for t in read_records(tmp_path / "killed", probe=True)] == [-1, 0, 1, 2]


def test_a_fault_retracts_along_the_force_axis_of_the_pose_reached() -> None:
    """The retract of a fault or of a resume in contact: back along the tool's axis."""
    from forcelearn.devices import Pose
    from forcelearn.tasks.path import PathTask

    config = load_cell_config(EXAMPLE)
    assert config.path_task is not None
    task = PathTask(object(), config.path_task, load_path(config), 10.0,  # type: ignore[arg-type]
                    stiffness_n_per_mm=2.0)
    for k, depth in ((0, 6.0), (13, 12.5), (26, -3.0)):
        pressed = task.points.pose(k, depth)
        back = task.away(pressed)
        expected = task.points.pose(k, -config.path_task.approach_mm)
        assert back.quaternion == pressed.quaternion
        assert [back.x_mm, back.y_mm, back.z_mm] == pytest.approx(
            [expected.x_mm, expected.y_mm, expected.z_mm], abs=1e-9)
    lifted = task.points.pose(4, -30.0)  # already further off: stays
    assert task.away(lifted) == Pose(lifted.x_mm, lifted.y_mm, lifted.z_mm, lifted.quaternion)


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
