"""The RAPID reader on modules written as robot programmers write them (tests/paths/modules)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from forcelearn.paths import read_rapid, read_rapid_text

MODULES = Path(__file__).parent / "modules"


def _rotation(wxyz: list[float]) -> Rotation:
    return Rotation.from_quat(np.array(wxyz)[[1, 2, 3, 0]])


def _in_base(uframe: tuple[list[float], list[float]], oframe: tuple[list[float], list[float]],
             point: list[float]) -> np.ndarray:
    """A point of the object frame in the base frame: uframe(oframe(point))."""
    in_user = np.array(oframe[0]) + _rotation(oframe[1]).apply(point)
    return np.array(uframe[0]) + _rotation(uframe[1]).apply(in_user)


def _same_rotation(a: np.ndarray, b: Rotation) -> bool:
    return bool((_rotation(list(a)).inv() * b).magnitude() < 1e-9)


def test_pendant_style_offs_and_wobj_give_base_frame_points_in_move_order() -> None:
    r"""One-line robtargets, ``\WObj:=``, Offs in the object frame; MoveAbsJ skipped and noted."""
    path = read_rapid(MODULES / "pendant_style.mod")
    user = ([600, -200, 150], [0.707106781, 0, 0, 0.707106781])
    identity = ([0, 0, 0], [1, 0, 0, 0])
    expected = [_in_base(user, identity, p) for p in
                ([0, 0, 80], [0, 0, 30], [100, 0, 30], [200, 0, 30], [200, 0, 80])]
    np.testing.assert_allclose(path.positions_mm, expected, atol=1e-6)
    turn = _rotation(user[1]) * _rotation([0, 1, 0, 0])
    assert all(_same_rotation(q, turn) for q in path.quaternions_wxyz)
    assert path.names[1:4] == ("pStart", "pMid", "pEnd")
    assert path.instructions[0] == "MoveJ" and set(path.tool_names) == {"tPad"}
    assert path.tools["tPad"].tcp.position_mm == (0.0, 0.0, 180.5)
    assert path.tools["tPad"].mass_kg == pytest.approx(1.2)
    assert len(path.notes) == 2 and all("MoveAbsJ" in note for note in path.notes)
    text = (MODULES / "pendant_style.mod").read_text().splitlines()
    assert all("Move" in text[line - 1] for line in path.lines)


def test_robotstudio_style_with_bom_crlf_and_a_called_path_proc() -> None:
    """Main calls Path_10, as RobotStudio generates; CRLF and a BOM do not shift line numbers."""
    path = read_rapid(MODULES / "robotstudio_style.mod")
    assert path.names == ("Target_10", "Target_20", "Target_30")
    assert path.positions_mm[2, 2] == pytest.approx(0.25)
    np.testing.assert_allclose(path.positions_mm[:, :2] - [400, 100],
                               [[-12.5, 40], [-12.5, 90], [-12.5, 140]])
    lines = (MODULES / "robotstudio_style.mod").read_text(encoding="utf-8-sig").splitlines()
    assert [lines[n - 1].split()[1].split(",")[0] for n in path.lines] == list(path.names)


def test_hand_written_style() -> None:
    """Lower case, split robtargets, arrays, an assignment, inline targets, MoveC, RelTool."""
    path = read_rapid(MODULES / "hand_written.mod", proc="ROLLERPASS")
    user = ([1000, 0, 500], [1, 0, 0, 0])
    obj = ([0, 0, 0], [0.7071068, 0.7071068, 0, 0])
    taught = [[0, 0, 300], [0, 0, 275], [0, 0, 250], [50, 0, 245], [100, 0, 230], [100, 0, 300]]
    np.testing.assert_allclose(path.positions_mm[:6], [_in_base(user, obj, p) for p in taught],
                               atol=1e-4)
    assert path.instructions[3:5] == ("MoveC", "MoveC") and path.names[3:5] == ("arc{2}", "arc{3}")
    # RelTool: the offset is along arc{3}'s own z, then the turn about x, the new y, the new z.
    arc3 = _rotation([0.9848078, 0, 0.1736482, 0])
    in_object = np.array([100, 0, 230]) + arc3.apply([0, 0, -10])
    np.testing.assert_allclose(path.positions_mm[6], _in_base(user, obj, list(in_object)),
                               atol=1e-4)
    expected = _rotation(obj[1]) * arc3 * Rotation.from_euler("XYZ", [10, 0, -20], degrees=True)
    assert _same_rotation(path.quaternions_wxyz[6], expected)
    assert "ERROR" not in "".join(path.names)  # the error handler's move is not the path
    assert len(path) == 7


def test_fc_pressure_program_is_read_as_its_path() -> None:
    """FCPress1LStart / FCPressL / FCPressC (two points) / FCPressEnd give the path in order."""
    path = read_rapid(MODULES / "fc_pressure.mod")
    assert path.instructions == ("FCPress1LStart", "FCPressL", "FCPressC", "FCPressC",
                                 "FCPressEnd")
    assert path.names[:4] == ("p10", "p20", "p30", "p40")
    np.testing.assert_allclose(path.positions_mm[-1] - path.positions_mm[-2], [0, 0, 50])
    assert set(path.tool_names) == {"tPolish"}


def test_several_procs_choose_by_name_and_refuse_an_unnamed_choice() -> None:
    """A PROC is chosen by name (case-insensitive); with no main and several PROCs, say which."""
    text = (MODULES / "hand_written.mod").read_text()
    assert len(read_rapid_text(text, "other")) == 1
    with pytest.raises(ValueError, match=r"rollerPass, other|other, rollerPass"):
        read_rapid_text(text)


_NO_AXES = "[9E9,9E9,9E9,9E9,9E9,9E9]"
DATA_MODULE = f"""MODULE Data
  CONST robtarget pA := [[1,2,3],[1,0,0,0],[0,0,0,0],{_NO_AXES}];
  LOCAL CONST robtarget pHidden := [[0,0,0],[1,0,0,0],[0,0,0,0],{_NO_AXES}];
ENDMODULE
"""
MAIN_MODULE = """MODULE Main
  PROC main()
    MoveL pA, v10, fine, tool0;
    MoveL Offs(pA,1,0,0), v10, fine, tool0;
  ENDPROC
ENDMODULE
"""


def test_a_program_over_two_modules(tmp_path: Path) -> None:
    """Data in one module, the PROC in another: globals are shared, LOCAL data is not."""
    files = [tmp_path / "data.mod", tmp_path / "main.mod"]
    files[0].write_text(DATA_MODULE)
    files[1].write_text(MAIN_MODULE)
    path = read_rapid(files)
    np.testing.assert_allclose(path.positions_mm, [[1, 2, 3], [2, 2, 3]])
    assert path.source == str(files[1])
    files[1].write_text(MAIN_MODULE.replace("Offs(pA,1,0,0)", "pHidden"))
    with pytest.raises(ValueError, match=r"main\.mod:4: unknown robtarget 'pHidden'"):
        read_rapid(files)
