"""examples/paths: reproducible from their generator, on their parts' foam skin, readable."""

from __future__ import annotations

import tomllib
from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from forcelearn.emulators.physics.part import Part, contact
from forcelearn.emulators.physics.part_table import part_from_table
from forcelearn.paths import PathLimits, read_path_csv, read_rapid, validate_path
from forcelearn.tools.path_examples import main

EXAMPLES = Path(__file__).parents[2] / "examples" / "paths"
PARTS = tomllib.loads((EXAMPLES / "parts.toml").read_text())


def _part(name: str) -> Part:
    table = {k: v for k, v in PARTS[name].items() if k not in ("path", "foam_thickness_mm")}
    return part_from_table(table, EXAMPLES)


def test_the_committed_examples_are_what_the_generator_writes() -> None:
    """``--check`` regenerates every file and compares it byte for byte."""
    assert main(["--check", "--out", str(EXAMPLES)]) == 0


def test_check_reports_a_changed_file(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """A file edited by hand is reported and the check fails."""
    main(["--out", str(tmp_path)])
    (tmp_path / "sphere-arc.csv").write_text("x_mm,y_mm,z_mm,qw,qx,qy,qz\n")
    assert main(["--check", "--out", str(tmp_path)]) == 1
    assert "sphere-arc.csv differs" in capsys.readouterr().err


@pytest.mark.parametrize("name", sorted(PARTS))
def test_each_path_is_on_its_parts_foam_skin_with_the_tool_against_the_normal(name: str) -> None:
    """Depth 0 at the foam's thickness off the part; the tool's z axis along -normal."""
    path = read_path_csv(EXAMPLES / PARTS[name]["path"])
    where = contact(_part(name), path.positions_mm, offset_mm=PARTS[name]["foam_thickness_mm"])
    np.testing.assert_allclose(where.depth_mm, 0.0, atol=1e-3)
    tool_z = Rotation.from_quat(path.quaternions_wxyz[:, [1, 2, 3, 0]]).apply([0.0, 0.0, 1.0])
    cosine = np.einsum("ij,ij->i", tool_z, -where.normal)
    assert np.all(cosine > np.cos(np.radians(0.1)))
    validate_path(path, PathLimits((700.0, -100.0, 0.0), (1100.0, 100.0, 300.0),
                                   max_step_mm=10.0, max_turn_deg=5.0, min_points=25))


def test_the_cylinder_arc_turns_the_tool_at_least_40_degrees() -> None:
    """The taught-path example: >= 25 points, the tool turning >= 40 deg from first to last."""
    path = read_path_csv(EXAMPLES / "cylinder-arc.csv")
    turns = Rotation.from_quat(path.quaternions_wxyz[:, [1, 2, 3, 0]])
    assert len(path) >= 25
    assert np.degrees((turns[0].inv() * turns[-1]).magnitude()) >= 40.0


def test_the_rapid_module_is_the_same_path_in_its_work_object() -> None:
    """cylinder-arc.mod (robtargets in wCylinder) reads to the CSV's poses."""
    module, csv = read_rapid(EXAMPLES / "cylinder-arc.mod"), read_path_csv(EXAMPLES /
                                                                        "cylinder-arc.csv")
    np.testing.assert_allclose(module.positions_mm, csv.positions_mm, atol=1e-3)
    a = Rotation.from_quat(module.quaternions_wxyz[:, [1, 2, 3, 0]])
    b = Rotation.from_quat(csv.quaternions_wxyz[:, [1, 2, 3, 0]])
    assert np.all(np.degrees((a.inv() * b).magnitude()) < 1e-3)
    assert module.names == csv.names and set(module.tool_names) == {"tRoller"}
    assert not np.allclose(module.positions_mm[:, :2] - [900.0, 0.0],
                           _object_xy(EXAMPLES / "cylinder-arc.mod")), "the wobj must matter"


def _object_xy(path: Path) -> np.ndarray:
    """The x, y written in the module's robtargets (in the work object's frame)."""
    rows = [line.split("[[", 1)[1].split("]", 1)[0].split(",")
            for line in path.read_text().splitlines() if "CONST robtarget" in line]
    return np.array([[float(r[0]), float(r[1])] for r in rows])
