"""CSV paths, and round trips: CSV text, a RAPID module in a work object, RAPID numbers."""

from __future__ import annotations

import contextlib
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from path_strategies import frames, taught_paths
from scipy.spatial.transform import Rotation

from forcelearn.errors import PathParseError
from forcelearn.paths import (
    Frame,
    TaughtPath,
    format_rapid_module,
    read_path_csv,
    read_rapid_text,
    write_path_csv,
)
from forcelearn.paths.csv_file import format_path_csv, parse_path_csv


def test_header_comments_blank_lines_and_names() -> None:
    """Columns by header name in any order; '#' lines and blank lines skipped; lines kept."""
    text = "# a taught path\nqw,qx,qy,qz,x_mm,y_mm,z_mm,name\n\n1,0,0,0,10,20,30,start\n" \
           "# half way\n0,1,0,0,11,21,31,end\n"
    path = parse_path_csv(text, "p.csv")
    np.testing.assert_array_equal(path.positions_mm, [[10, 20, 30], [11, 21, 31]])
    np.testing.assert_array_equal(path.quaternions_wxyz, [[1, 0, 0, 0], [0, 1, 0, 0]])
    assert path.names == ("start", "end") and path.lines == (4, 6)


def test_without_header_seven_or_eight_columns() -> None:
    """No header: the documented order, with an optional name column."""
    path = parse_path_csv("1,2,3,1,0,0,0\n4,5,6,1,0,0,0,p2\n")
    assert path.names == ("", "p2")
    np.testing.assert_array_equal(path.positions_mm[1], [4, 5, 6])


@pytest.mark.parametrize(("text", "line", "reason"), [
    ("x_mm,y_mm,z_mm,qw,qx,qy\n", 1, "missing"),
    ("x_mm,y_mm,z_mm,qw,qx,qy,qz,speed\n", 1, "unknown"),
    ("1,2,3,1,0,0,0\n1,2,3,1,0,0\n", 2, "got 6 fields"),
    ("1,2,3,1,0,0,0\n1,2,x,1,0,0,0\n", 2, "not a number"),
    ("1,2,3,1,0,0,0\n1,2,inf,1,0,0,0\n", 2, "not finite"),
    ("# only a comment\n", 0, "no pose"),
])
def test_bad_csv_is_refused_naming_the_line(text: str, line: int, reason: str) -> None:
    """Every CSV refusal is a PathParseError at the line that is wrong."""
    with pytest.raises(PathParseError, match=reason) as caught:
        parse_path_csv(text, "p.csv")
    assert caught.value.line == line


@settings(max_examples=25)
@given(taught_paths())
def test_csv_round_trip(path: TaughtPath) -> None:
    """Format then parse gives back the same poses and names, bit for bit."""
    back = parse_path_csv(format_path_csv(path))
    np.testing.assert_array_equal(back.positions_mm, path.positions_mm)
    np.testing.assert_array_equal(back.quaternions_wxyz, path.quaternions_wxyz)
    assert back.names == path.names


def test_csv_file_round_trip(tmp_path: Path) -> None:
    """write_path_csv / read_path_csv through a file."""
    path = TaughtPath(np.array([[1.5, 2, 3], [4, 5, 6.25]]), np.array([[1, 0, 0, 0]] * 2))
    write_path_csv(tmp_path / "p.csv", path)
    back = read_path_csv(tmp_path / "p.csv")
    np.testing.assert_array_equal(back.positions_mm, path.positions_mm)
    assert back.source == str(tmp_path / "p.csv") and back.lines == (2, 3)


@settings(max_examples=20)
@given(taught_paths(), frames())
def test_rapid_module_round_trip_through_a_work_object(path: TaughtPath, wobj: Frame) -> None:
    """A path written in a work object's frame reads back to the same base-frame poses."""
    back = read_rapid_text(format_rapid_module(path, wobj=wobj))
    np.testing.assert_allclose(back.positions_mm, path.positions_mm, atol=1e-6)
    turns = Rotation.from_quat(back.quaternions_wxyz[:, [1, 2, 3, 0]])
    taught = Rotation.from_quat(path.quaternions_wxyz[:, [1, 2, 3, 0]])
    assert np.all((turns.inv() * taught).magnitude() < 1e-9)
    assert all(back.instructions[i] == "MoveL" for i in range(len(back)))
    if any(path.names):
        assert back.names == path.names


@settings(max_examples=60)
@given(st.floats(-1e12, 1e12, allow_nan=False), st.sampled_from(["{:.6E}", "{:e}", "{!r}",
                                                                  "{:.3f}", "{:G}"]))
def test_rapid_numbers_in_every_notation(value: float, form: str) -> None:
    """A coordinate in plain, E or e notation reads as Python reads the same text."""
    text = form.format(value)
    module = (f"MODULE M\n CONST robtarget p := [[{text},0,0],[1,0,0,0],[0,0,0,0],"
              "[9E+09,9E9,9.0E+09,9e9,9E09,9E+9]];\n PROC main()\n  MoveL p,v10,fine,tool0;\n"
              " ENDPROC\nENDMODULE\n")
    assert read_rapid_text(module).positions_mm[0, 0] == float(text)


@settings(max_examples=80)
@given(st.text(alphabet="0123456789.,-e#\n xyzqwmn_\"", max_size=200))
def test_any_text_is_read_or_refused_never_crashes(text: str) -> None:
    """CSV-like noise gives a path or a PathParseError, nothing else."""
    with contextlib.suppress(PathParseError):
        parse_path_csv(text)
