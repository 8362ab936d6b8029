"""The path task's [task] keys: parsed, refused naming the key, the path checked before moves."""

from __future__ import annotations

import tomllib
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from forcelearn.errors import ConfigError, PathParseError, PathRefused
from forcelearn.paths import read_path_csv
from forcelearn.tasks.path_spec import (
    PathTaskSpec,
    build_path_task,
    load_task_path,
    task_kind,
)

EXAMPLES = Path(__file__).parents[2] / "examples" / "paths"
WORKSPACE = ((700.0, -100.0, 0.0), (1100.0, 100.0, 300.0))


def test_kind_defaults_to_the_surface_task_and_unknown_kinds_are_named() -> None:
    """No table or no kind: §5; "path" the path task; anything else refused with the choices."""
    assert task_kind(None) == task_kind({}) == "surface"
    assert task_kind({"kind": "path"}) == "path"
    with pytest.raises(ConfigError, match=r"task.kind = 'contour': must be one of surface, path"):
        task_kind({"kind": "contour"})


def test_a_table_builds_with_its_path_relative_to_the_config_file(tmp_path: Path) -> None:
    """``path`` is relative to the config's folder; the evaluation is §5's with this force."""
    spec = build_path_task({"kind": "path", "path": "cylinder-arc.mod", "proc": "main",
                            "desired_force_n": 30, "force_axis": [0, 0, 1]}, EXAMPLES)
    assert Path(spec.path) == EXAMPLES / "cylinder-arc.mod"
    assert spec.evaluation.desired_force_n == 30 and spec.evaluation.tolerance_n == 15
    assert spec.contact_force_n == pytest.approx(30 * spec.contact_threshold_pct / 100)
    absolute = build_path_task({"path": str(tmp_path / "p.csv")}, EXAMPLES)
    assert absolute.path == str(tmp_path / "p.csv")


BAD: dict[str, tuple[dict[str, Any], str]] = {
    "unknown key": ({"speed": 5}, r"unknown key\(s\) task.speed"),
    "no path": ({"path": ""}, "task.path: give the taught path"),
    "other file": ({"path": "p.txt"}, r"task.path = 'p.txt': a .csv file or a RAPID module"),
    "proc with a CSV": ({"path": "p.csv", "proc": "main"}, "task.proc applies to RAPID"),
    "axis not unit": ({"force_axis": [0, 0, 2]}, "task.force_axis .* a unit vector"),
    "axis of two": ({"force_axis": [0, 1]}, "task.force_axis"),
    "negative force": ({"desired_force_n": -5}, r"task.desired_force_n = -5: .* > 0"),
    "threshold 0": ({"contact_threshold_pct": 0}, "task.contact_threshold_pct = 0"),
    "threshold 100": ({"contact_threshold_pct": 100}, "task.contact_threshold_pct = 100"),
    "ramp": ({"force_ramp_n_s": 0}, "task.force_ramp_n_s = 0"),
    "deviation": ({"max_deviation_mm": float("inf")}, "task.max_deviation_mm = inf"),
    "approach": ({"approach_mm": -1}, "task.approach_mm = -1"),
    "one point": ({"points_per_pass": 1}, "task.points_per_pass = 1"),
    "points as text": ({"points_per_pass": "40"}, "task.points_per_pass"),
    "contact loss": ({"on_contact_loss": "chase"}, "task.on_contact_loss = 'chase': one of"),
    "turn": ({"max_turn_deg": 0}, "task.max_turn_deg = 0"),
    "press stiffness": ({"press_stiffness_n_per_mm": 0}, "task.press_stiffness_n_per_mm = 0"),
    "zero check": ({"zero_check": "yes"}, "task.zero_check = 'yes'"),
}


@pytest.mark.parametrize("case", sorted(BAD))
def test_each_bad_key_is_refused_naming_it(case: str) -> None:
    """A ConfigError whose message names task.<key> and what it must be."""
    table, message = BAD[case]
    with pytest.raises(ConfigError, match=message):
        build_path_task({"path": "p.mod", **table}, None)


def test_the_example_path_loads_resampled_and_checked() -> None:
    """The cylinder arc, resampled to 40 points per pass, within the example workspace."""
    spec = PathTaskSpec(path=str(EXAMPLES / "cylinder-arc.csv"), points_per_pass=40)
    path = load_task_path(spec, *WORKSPACE, max_step_mm=10.0)
    taught = read_path_csv(EXAMPLES / "cylinder-arc.csv")
    assert len(path) == 40
    np.testing.assert_allclose(path.positions_mm[[0, -1]], taught.positions_mm[[0, -1]])


def test_the_path_is_refused_before_any_move() -> None:
    """A step beyond safety.max_step_mm, an approach outside the workspace, a missing PROC."""
    spec = PathTaskSpec(path=str(EXAMPLES / "cylinder-arc.csv"))
    with pytest.raises(PathRefused, match="more than max_step_mm = 4"):
        load_task_path(spec, *WORKSPACE, max_step_mm=4.0)
    far = PathTaskSpec(path=spec.path, approach_mm=200.0)
    with pytest.raises(PathRefused, match=r"approach point .*\(task.approach_mm\), is outside"):
        load_task_path(far, *WORKSPACE, max_step_mm=10.0)
    module = PathTaskSpec(path=str(EXAMPLES / "cylinder-arc.mod"), proc="polish")
    with pytest.raises(PathParseError, match="no PROC 'polish'"):
        load_task_path(module, *WORKSPACE, max_step_mm=10.0)


def test_the_documented_table_is_the_defaults() -> None:
    """docs/path.md's [task] example builds to the spec's defaults (so the page cannot drift)."""
    page = (Path(__file__).parents[2] / "docs" / "path.md").read_text()
    blocks = [part.split("```", 1)[0] for part in page.split("```toml\n")[1:]]
    block = next(b for b in blocks if b.startswith("[task]\nkind = \"path\""))
    table = tomllib.loads(block)["task"]
    root = Path(__file__).parents[2]
    assert build_path_task(table, root) == PathTaskSpec(path=str(root / table["path"]))
