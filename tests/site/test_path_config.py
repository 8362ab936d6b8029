"""``[task] kind = "path"`` and ``[emulator.part]`` in a cell config; refusals name the key."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import pytest

from forcelearn.emulators.physics.part import Cylinder
from forcelearn.errors import ConfigError, PathRefused
from forcelearn.paths import read_path_csv
from forcelearn.site import load_cell_config
from forcelearn.tools.experiments.path_run import load_path, run_path

EXAMPLES = Path(__file__).resolve().parents[2] / "examples" / "paths"
CYLINDER_PART = """
[emulator.part]
shape = "cylinder"
point_mm = [900, 0, 0]
axis = [0, 1, 0]
radius_mm = 110
"""


def write(tmp_path: Path, text: str) -> Path:
    """A config file in ``tmp_path`` (the example's path beside it)."""
    (tmp_path / "arc.csv").write_bytes((EXAMPLES / "cylinder-arc.csv").read_bytes())
    path = tmp_path / "cell.toml"
    path.write_text(text, encoding="utf-8")
    return path


def test_a_path_config_builds_the_part_the_task_and_the_filter_axis(tmp_path: Path) -> None:
    """Path relative to the config; the part read; the filter reads -Fz (tool z presses)."""
    config = load_cell_config(write(tmp_path, '[task]\nkind = "path"\npath = "arc.csv"\n'
                                    + CYLINDER_PART))
    assert config.path_task is not None
    assert Path(config.path_task.path) == tmp_path / "arc.csv"
    assert config.emulator.part is not None and isinstance(config.emulator.part.part, Cylinder)
    assert (config.filter.axis, config.filter.sign) == (2, -1.0)
    assert len(load_path(config)) == 27


def test_the_path_option_makes_any_config_a_path_run(tmp_path: Path) -> None:
    """``--path`` replaces a §5 [task] table; without it the §5 task stays."""
    file = write(tmp_path, '[task]\ndesired_force_n = 19.6133\n')
    assert load_cell_config(file).path_task is None
    config = load_cell_config(file, task_path=tmp_path / "arc.csv")
    assert config.path_task is not None and config.path_task.path.endswith("arc.csv")


@pytest.mark.parametrize(("text", "key"), [
    ('[task]\nkind = "path"\npath = "arc.csv"\nforce_axis = [0.6, 0.0, 0.8]\n', "force_axis"),
    ('[emulator.part]\nshape = "cylinder"\npoint_mm = [0, 0, 0]\naxis = [0, 1, 0]\n'
     'radius_mm = 1\ncolour = "red"\n', "emulator.part.colour"),
    ('[emulator.part]\nshape = "plane"\npoint_mm = [0, 0, 0]\nnormal = [0, 0, 1]\n'
     'gap_min_mm = [1, 1, 1]\n', "gap_max_mm"),
    ('[emulator.part]\nshape = "plane"\npoint_mm = [0, 0, 0]\nnormal = [0, 0, 1]\n'
     'tip_radius_mm = -2\n', "tip_radius_mm"),
])
def test_a_bad_key_is_refused_by_name(tmp_path: Path, text: str, key: str) -> None:
    """Each refusal names the key to fix."""
    with pytest.raises(ConfigError, match=key):
        load_cell_config(write(tmp_path, text))


def test_a_path_whose_deviation_leaves_the_workspace_is_refused_before_any_move(
        tmp_path: Path) -> None:
    """Points ± max_deviation_mm along the force axis must stay in the workspace."""
    config = load_cell_config(write(tmp_path, '[task]\nkind = "path"\npath = "arc.csv"\n'
                                    + CYLINDER_PART))
    assert config.path_task is not None
    lowest = float(read_path_csv(config.path_task.path).positions_mm[:, 2].min())
    low = config.safety.workspace_min_mm
    tight = replace(config, safety=replace(config.safety, workspace_min_mm=(
        low[0], low[1], lowest - 5.0)))  # the points fit; 15 mm deeper along the axis does not
    with pytest.raises(PathRefused, match="max_deviation_mm"):
        load_path(tight)


def test_run_path_refuses_a_bad_path_before_the_cell_opens(tmp_path: Path) -> None:
    """A non-unit quaternion on line 3: refused naming it, nothing written, nothing opened."""
    rows = (EXAMPLES / "cylinder-arc.csv").read_text().splitlines()
    fields = rows[2].split(",")
    fields[3] = "0.5"  # qw: |q| is no longer 1
    rows[2] = ",".join(fields)
    config = load_cell_config(write(tmp_path, '[task]\nkind = "path"\npath = "bad.csv"\n'
                                    + CYLINDER_PART))
    (tmp_path / "bad.csv").write_text("\n".join(rows) + "\n")
    out = tmp_path / "run"
    with pytest.raises(PathRefused, match="line 3"):
        run_path(config, out, passes=1, seed=0)
    assert not out.exists()


def test_a_force_the_safety_limit_would_stop_is_refused(tmp_path: Path) -> None:
    """The desired force and its tolerance must fit under safety.max_force_n."""
    config = load_cell_config(write(tmp_path, '[task]\nkind = "path"\npath = "arc.csv"\n'
                                    'desired_force_n = 150.0\n' + CYLINDER_PART))
    with pytest.raises(ConfigError, match=r"safety\.max_force_n"):
        load_path(config)


def test_the_emulated_cell_without_a_part_is_refused_for_a_path(tmp_path: Path) -> None:
    """``--path`` on the default emulated cell: no part to press, said before any move."""
    config = load_cell_config(write(tmp_path, ""), task_path=tmp_path / "arc.csv")
    with pytest.raises(ConfigError, match=r"\[emulator\.part\]"):
        load_path(config)
