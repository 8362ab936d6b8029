"""The path task end to end on the emulated cell (computer link + JR3), the tool turning."""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np
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


def test_a_sensor_reboot_mid_pass_retracts_along_the_axis_and_runs_the_pass_again(
        tmp_path: Path) -> None:
    """Reboot while pressing in pass 1: retract back along the axis, re-zero, pass 1 again.

    Then a resume of a run marked as stopped in contact retracts (and re-zeroes) first.
    """
    from unittest import mock

    from forcelearn.site import CellSession
    from forcelearn.tools.experiments import path_run
    from forcelearn.tools.experiments.fault_recovery import IN_CONTACT_FILE, read_events
    from forcelearn.tools.experiments.path_state import prepare_path_run
    from forcelearn.tools.experiments.records import read_records

    out = tmp_path / "run"
    fired: list[int] = []

    class Rebooting(CellSession):
        def __init__(self, *args: object, **kwargs: object) -> None:
            super().__init__(*args, **kwargs)  # type: ignore[arg-type]
            cell, measure = self.cell, self.cell.measure_force_n  # type: ignore[union-attr]

            def measured(samples: int | None = None) -> float:
                if not fired and cell.stage == ("step", 3) and (out / "checkpoint.npz").exists():
                    fired.append(1)
                    self.sensor_emulator.inject_bootup()
                return measure(samples)

            cell.measure_force_n = measured  # type: ignore[method-assign,union-attr]

    config = short_config(tmp_path)
    run, _ = prepare_path_run(config, None, out, 2, 0, 25, resume=False)
    with mock.patch.object(path_run, "CellSession", Rebooting):
        summary = path_run.execute(run, None, figures=False)
    events = read_events(out)
    assert fired and [(e["error"], e["action"], e["trial"]) for e in events] == [
        ("SensorRebooted", "resumed", 1)]
    assert summary["passes"] == 2 and summary["faults"]["resumed"] == 1
    trials = {t.trial: t for t in read_records(out)}
    assert sorted(trials) == [0, 1]
    tare = trials[1].tares[0]  # the re-zero where the retract ended: free space on the axis
    assert tare.accepted
    assert run.task is not None
    points = run.task.points
    k = int(np.argmin(np.linalg.norm(points.positions_mm - tare.position_mm, axis=1)))
    lifted = points.pose(k, -20.0)
    assert tare.position_mm == pytest.approx((lifted.x_mm, lifted.y_mm, lifted.z_mm), abs=0.5)

    (out / IN_CONTACT_FILE).write_text("{}")  # as a second Ctrl-C during a retract leaves it
    resumed, state = prepare_path_run(None, None, out, 3, None, 25, resume=True)
    path_run.execute(resumed, state, figures=False)
    assert read_events(out)[-1]["action"] == "retracted on resume"
    assert not (out / IN_CONTACT_FILE).exists()


def test_a_sensor_mounted_at_an_angle_reads_the_force_along_the_tool_axis(
        tmp_path: Path) -> None:
    """The calibration's mounting turns the tool's force axis into the sensor's frame.

    A sensor turned 20, -30, 45 deg on the flange sees the tool's z at 0.81 of its own z:
    read on one axis the probe would fit a foam 19 % softer than the straight cell's.
    """
    import dataclasses

    from forcelearn.calibration import load_calibration, save_calibration
    from forcelearn.site.emulated_tool import load_mounting
    from forcelearn.tools.experiments.path_run import execute
    from forcelearn.tools.experiments.path_state import prepare_path_run

    mounting = load_mounting({"mounting_rpy_deg": [20.0, -30.0, 45.0]})
    assert mounting is not None
    straight = load_calibration(EXAMPLE.parent / "emulated-jr3-cal.toml")
    save_calibration(dataclasses.replace(straight, tool=dataclasses.replace(
        straight.tool, mounting_quaternion=mounting)), tmp_path / "turned-cal.toml")
    stiffness = {}
    for name in ("straight", "turned"):
        folder = tmp_path / name
        folder.mkdir()
        extra = "" if name == "straight" else \
            "[emulator.tool]\nmounting_rpy_deg = [20.0, -30.0, 45.0]\n"
        config = short_config(folder, extra)
        if name == "turned":
            config.write_text(config.read_text().replace(
                str(EXAMPLE.parent / "emulated-jr3-cal.toml"), str(tmp_path / "turned-cal.toml")))
        run, _ = prepare_path_run(config, None, folder / "run", 1, 0, 25, resume=False)
        assert (run.config.filter.direction is None) == (name == "straight")
        summary = execute(run, None, figures=False)
        stiffness[name] = summary["probe_stiffness_n_per_mm"]
        assert summary["final_force_rms_n"] < 0.05 * 19.6133
    assert stiffness["turned"] == pytest.approx(stiffness["straight"], rel=0.05)
