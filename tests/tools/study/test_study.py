"""`forcelearn study`: the grid, the tables, resuming, and the same table on a Dask cluster."""

import csv
import json
from pathlib import Path
from typing import Any

import pytest

from forcelearn.errors import ConfigError
from forcelearn.tools.cli import main
from forcelearn.tools.experiments.contour import ContourConfig
from forcelearn.tools.study.grid import apply_overrides, grid_points, parse_sets
from forcelearn.tools.study.runner import run_study
from forcelearn.tools.study.tasks import get_task

TIMING = {"wall_s", "steps_per_s", "batch_size"}
POINTS = grid_points({"learner.gamma": [0.8, 0.9], "learner.extent": [(3, 3), (5, 5)]})


def _table(rows: list[dict[str, Any]]) -> list[dict[str, Any]]:
    return [{k: v for k, v in r.items() if k not in TIMING} for r in rows]


def test_set_keys_resolve_and_values_take_the_default_type() -> None:
    """Bare names, the alias d, tuples a:b, a single value repeated, booleans."""
    grid = parse_sets(
        ContourConfig(),
        ["gamma=0.8,0.9", "d=5,3:4", "generalized_phase=true,false", "task.theta1_parts=50"],
    )
    assert grid == {
        "learner.gamma": [0.8, 0.9],
        "learner.extent": [(5, 5), (3, 4)],
        "learner.generalized_phase": [True, False],
        "task.theta1_parts": [50],
    }
    assert len(grid_points(grid)) == 8
    config = apply_overrides(ContourConfig(), {"learner.gamma": 0.7, "geometry.servo_lag": 0.2})
    assert config.learner.gamma == 0.7 and config.geometry.servo_lag == 0.2


def test_an_unset_optional_key_takes_a_number_or_none() -> None:
    """A key whose default is None is typed by its annotation (it was passed on as text).

    ``none`` keeps it unset; a word where a number belongs fails before any run.
    """
    from forcelearn.tools.study.baselines import BaselinesConfig

    grid = parse_sets(BaselinesConfig(), ["cma.sigma0_mm=1.5,none,2"])
    assert grid == {"cma.sigma0_mm": [1.5, None, 2.0]}
    assert all(isinstance(v, float) for v in (grid["cma.sigma0_mm"][0], grid["cma.sigma0_mm"][2]))
    with pytest.raises(ConfigError, match="cannot read 'deep'"):
        parse_sets(BaselinesConfig(), ["cma.sigma0_mm=deep"])
    surface = get_task("surface").base_config()
    grid = parse_sets(surface, ["task.tolerance_n=5", "sensor.log_path=jr3.blf",
                                "sensor.full_scales=100:100:200:10:10:10"])
    assert grid == {
        "task.tolerance_n": [5.0],
        "sensor.log_path": ["jr3.blf"],
        "sensor.full_scales": [(100.0, 100.0, 200.0, 10.0, 10.0, 10.0)],
    }


def test_a_bad_key_is_named_with_the_valid_ones(capsys: pytest.CaptureFixture[str]) -> None:
    """An unknown --set key fails before any run, naming it and listing the keys."""
    with pytest.raises(ConfigError, match=r"unknown --set key 'gama'.*learner\.gamma"):
        parse_sets(ContourConfig(), ["gama=0.8"])
    with pytest.raises(ConfigError, match="cannot read 'x'"):
        parse_sets(ContourConfig(), ["gamma=x"])
    assert main(["study", "contour", "--set", "gama=1", "--out", "unused"]) == 1
    assert "valid keys" in capsys.readouterr().err


def test_study_writes_tidy_table_summary_and_heatmap(tmp_path: Path) -> None:
    """One row per run with every parameter, one summary row per point, one heatmap."""
    out = tmp_path / "study"
    code = main(
        [
            "study",
            "contour",
            "--seeds",
            "2",
            "--trials",
            "20",
            "--set",
            "gamma=0.8,0.9",
            "--set",
            "d=3,5",
            "--workers",
            "1",
            "--out",
            str(out),
            "--no-progress",
        ]
    )
    assert code == 0
    with (out / "runs.csv").open() as handle:
        rows = list(csv.DictReader(handle))
    assert len(rows) == 8
    assert {
        "learner.gamma",
        "learner.extent",
        "geometry.stiffness_n_per_m",
        "converged_trial",
        "final_force_rms_n",
        "seed",
    } <= set(rows[0])
    assert {(r["learner.gamma"], r["learner.extent"]) for r in rows} == {
        ("0.8", "3:3"),
        ("0.8", "5:5"),
        ("0.9", "3:3"),
        ("0.9", "5:5"),
    }
    with (out / "summary.csv").open() as handle:
        summary = list(csv.DictReader(handle))
    assert len(summary) == 4 and all(s["runs"] == "2" for s in summary)
    assert (out / "heatmap_learner-gamma__learner-extent.png").stat().st_size > 0
    assert json.loads((out / "study.json").read_text())["keys"] == [
        "learner.gamma",
        "learner.extent",
    ]


def test_an_interrupted_study_resumes_with_only_the_missing_runs(tmp_path: Path) -> None:
    """Stop after the first chunk; the restart runs the rest; the table equals a clean run's."""
    task = get_task("contour")
    clean = run_study(task, tmp_path / "clean", 15, range(2), POINTS, workers=1, progress=False)

    def stop(rows: list[dict[str, Any]]) -> None:
        raise KeyboardInterrupt

    out = tmp_path / "resumed"
    with pytest.raises(KeyboardInterrupt):
        run_study(
            task, out, 15, range(2), POINTS, workers=1, batch=2, progress=False, on_chunk=stop
        )
    done = len(list((out / "runs").glob("*.json")))
    assert 0 < done < 8
    resumed = run_study(task, out, 15, range(2), POINTS, workers=1, batch=2, progress=False)
    assert (resumed.reused, resumed.ran) == (done, 8 - done)
    assert _table(resumed.rows) == _table(clean.rows)


def test_a_dask_local_cluster_gives_the_local_table(tmp_path: Path) -> None:
    """--scheduler on a distributed.LocalCluster: the same rows as the local processes."""
    distributed = pytest.importorskip("distributed")
    task = get_task("contour")
    local = run_study(task, tmp_path / "local", 15, range(2), POINTS, workers=2, progress=False)
    with distributed.LocalCluster(
        n_workers=1,
        threads_per_worker=2,
        processes=False,
        protocol="tcp",
        dashboard_address=None,
    ) as cluster:
        assert cluster.scheduler_address.startswith("tcp://")
        remote = run_study(
            task,
            tmp_path / "dask",
            15,
            range(2),
            POINTS,
            scheduler=cluster.scheduler_address,
            progress=False,
        )
    assert remote.ran == 8
    assert _table(remote.rows) == _table(local.rows)


def test_surface_study_applies_the_override_to_the_emulated_cell_run(tmp_path: Path) -> None:
    """A §5 run through the study adapter sees its --set value (here the desired force)."""
    out = tmp_path / "surface"
    code = main(
        [
            "study",
            "surface",
            "--seeds",
            "1",
            "--trials",
            "2",
            "--set",
            "task.desired_force_n=15",
            "--workers",
            "1",
            "--out",
            str(out),
            "--no-progress",
        ]
    )
    assert code == 0
    with (out / "runs.csv").open() as handle:
        (row,) = list(csv.DictReader(handle))
    assert row["task.desired_force_n"] == "15.0" and float(row["desired_force_n"]) == 15.0
    assert row["trials"] == "2" and row["task"] == "surface"
